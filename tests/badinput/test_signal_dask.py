"""SIGINT and SIGTERM end ``catalog import --dask`` at any moment: 130/143, one line, nothing left.

The issue's cases: SIGTERM in the first second (while pandas' compiled modules import) was
turned by them into an AttributeError traceback; SIGTERM while the local cluster started left
``$TMPDIR/starsense-dask-*`` behind (the start cut short, its workers still running); a Ctrl-C
then was lost (SIGINT ignored process-wide while the workers were spawned) and the whole
catalogue written, exit 0. The real command runs here as a subprocess with ``TMPDIR`` pointed
at a folder of the test; the signal goes to the command alone or, as a terminal's Ctrl-C
does, to its whole process group (the workers too).
"""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from starsense.cli import main

pytest.importorskip("hats_import")
pytest.importorskip("distributed")

cli_app = importlib.import_module("starsense.cli.app")

LINES = {
    signal.SIGINT: (130, "error: interrupted (Ctrl-C); nothing written"),
    signal.SIGTERM: (143, "error: terminated (SIGTERM); nothing written"),
}


@pytest.fixture(scope="module")
def catalogue(tmp_path_factory) -> Path:
    """A CSV catalogue big enough that the import outlasts the signals (seeded)."""
    rng = np.random.default_rng(50)
    n = 400_000
    ra = rng.uniform(0.0, 360.0, n)
    dec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    mag = rng.uniform(0.0, 12.0, n)
    path = tmp_path_factory.mktemp("cat") / "stars.csv"
    np.savetxt(path, np.c_[ra, dec, mag], delimiter=",", header="ra,dec,V", comments="", fmt="%.6f")
    return path


def _run(catalogue: Path, folder: Path, signum: int, delay_s: float, group: bool) -> None:
    tmp = folder / "tmp"
    tmp.mkdir()
    out = folder / "hats"
    cmd = [sys.executable, "-c", "from starsense.cli import console_main; console_main()"]
    args = ["catalog", "import", str(catalogue), str(out), "--dask", "local:2"]
    proc = subprocess.Popen(
        [*cmd, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "TMPDIR": str(tmp)},
        start_new_session=True,  # its own process group: a group signal reaches no one else
    )
    time.sleep(delay_s)
    if group:
        os.killpg(proc.pid, signum)
    else:
        proc.send_signal(signum)
    try:
        _, err = proc.communicate(timeout=90)
    except subprocess.TimeoutExpired:  # pragma: no cover - the failure this test is about
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise AssertionError(f"signal {signum} at {delay_s} s: the command did not end") from None
    text = err.decode(errors="replace")
    code, line = LINES[signum]
    what = (signum, delay_s, group, proc.returncode, text[-2000:])
    if proc.returncode == 0:  # pragma: no cover - the import finished before the signal
        pytest.fail(f"the import ended before the signal: make the catalogue bigger {what}")
    assert proc.returncode == code, what
    assert text.strip() == line, what  # one line: no traceback, none from a worker
    assert list(tmp.iterdir()) == [], what  # no starsense-dask-* scratch folder
    assert not out.exists(), what


# the moments: pandas' import (~1 s), the cluster's start (~1.5-3 s), the import's work
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_while_the_cluster_starts(catalogue, tmp_path, signum):
    _run(catalogue, tmp_path, signum, 2.0, group=True)


@pytest.mark.slow
@pytest.mark.parametrize("group", [False, True], ids=["process", "group"])
@pytest.mark.parametrize("delay_s", [0.9, 1.2, 1.6, 2.2, 3.0, 4.0])
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_at_any_moment(catalogue, tmp_path, signum, delay_s, group):
    _run(catalogue, tmp_path, signum, delay_s, group)


def test_a_signal_a_library_turned_into_its_own_error_still_ends_the_command(
    tmp_path, monkeypatch, capsys
):
    # pandas' compiled modules, interrupted while they import, catch the unwind and raise
    # "partially initialized module" instead: the signal decides the outcome, not that error
    def import_swallowing_the_signal(*args, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)  # the handler raises here
        except BaseException:
            raise AttributeError("partially initialized module 'pandas'") from None
        raise AssertionError("SIGTERM did not arrive")  # pragma: no cover

    monkeypatch.setattr(cli_app, "_load", import_swallowing_the_signal)
    code = main(["trade", "--vary", "exposure_s=0.1,0.2", "--out", str(tmp_path / "out")])
    assert code == 143
    assert capsys.readouterr().err.strip() == LINES[signal.SIGTERM][1]
    assert list(tmp_path.iterdir()) == []


def test_an_error_without_a_signal_is_not_called_one(monkeypatch):
    # the mapping above is for a signal received: a plain bug still shows as itself
    def broken(*args, **kwargs):
        raise AttributeError("a bug")

    monkeypatch.setattr(cli_app, "_load", broken)
    with pytest.raises(AttributeError, match="a bug"):
        main(["trade", "--vary", "exposure_s=0.1,0.2"])
