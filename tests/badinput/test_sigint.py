"""Ctrl-C (SIGINT) ends a command with one line and status 130: no traceback, nothing left.

Start-up is where Ctrl-C used to print a KeyboardInterrupt traceback: the command's modules
take seconds to import, before typer (which says "Aborted!", status 1) runs. In-process tests
send SIGINT to the test process itself at chosen points (while the command's module loads,
while the report works); a slow test interrupts the real commands from outside at a few
moments of their start-up.
"""

from __future__ import annotations

import importlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import starsense.report.build as build
from starsense.cli import main
from starsense.cli.app import EXIT_INTERRUPTED

LINE = "error: interrupted (Ctrl-C); nothing written"
#: the module (``starsense.cli.app`` as an attribute is the app, by the package's __getattr__)
cli_app = importlib.import_module("starsense.cli.app")

#: the commands of the issue, each writing into the folder {out}
COMMANDS = {
    "datasheet": ["datasheet", "--trials", "2", "--out", "{out}"],
    "trade": ["trade", "--vary", "exposure_s=0.1,0.2", "--out", "{out}"],
    "report": ["report", "--out", "{out}"],
}


@pytest.fixture(autouse=True)
def _python_ctrl_c():
    """Each test starts with Python's own SIGINT handler (what a user's process has).

    In the whole suite an earlier test leaves SIGINT ignored in the test process (not found
    yet); the commands give back the handler they found, so the check of that would fail.
    """
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def _interrupt(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGINT)
    raise AssertionError("SIGINT did not interrupt")  # pragma: no cover


def _argv(name: str, out: Path) -> list[str]:
    return [a.format(out=out) for a in COMMANDS[name]]


@pytest.mark.parametrize("name", COMMANDS)
def test_ctrl_c_while_the_command_loads(name, tmp_path, monkeypatch, capsys):
    # the command's module is being imported (what takes seconds at start-up)
    monkeypatch.setattr(cli_app, "_load", _interrupt)
    code = main(_argv(name, tmp_path / "out"))
    err = capsys.readouterr().err
    assert code == EXIT_INTERRUPTED == 130
    assert err.strip() == LINE  # one line, no traceback
    assert list(tmp_path.iterdir()) == []
    # the handlers are given back: the test process's Ctrl-C is Python's again
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_while_the_report_loads_its_stars(tmp_path, monkeypatch, capsys):
    out = tmp_path / "r"
    out.mkdir()
    (out / "report.json").write_text(json.dumps({"generator": "starsense.report"}))
    (out / "index.html").write_text("old report")
    monkeypatch.setattr(build, "_load_stars", _interrupt)
    code = main(["report", "--out", str(out)])
    assert code == 130 and capsys.readouterr().err.strip() == LINE
    assert (out / "index.html").read_text() == "old report"  # the earlier report stands
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]  # no temporary left


def test_files_completed_in_a_discarded_staging_folder_are_not_reported(
    tmp_path, monkeypatch, capsys
):
    # the report completes its figures inside a staging folder; Ctrl-C before that folder is
    # renamed into place discards it: nothing of it is the user's, so "nothing written"
    from starsense._io import atomic_paths

    def write_then_interrupt(work, *args, **kwargs):
        with atomic_paths([work / "figure.pdf"]) as (tmp,):
            tmp.write_bytes(b"%PDF")
        assert (work / "figure.pdf").exists()  # complete, in the staging folder
        _interrupt()

    monkeypatch.setattr(build, "_write_index", write_then_interrupt)
    monkeypatch.setattr(build, "SECTION_BUILDERS", [])
    code = main(["report", "--out", str(tmp_path / "r")])
    assert code == 130 and capsys.readouterr().err.strip() == LINE
    assert list(tmp_path.iterdir()) == []  # the staging folder is gone with its figure


def _interrupt_and_swallow(*args, **kwargs):
    # what a library that catches everything does (an import whose unwind became an
    # ImportError it passed over): the signal arrived, the command goes on
    try:
        _interrupt()
    except BaseException:
        pass


def test_ctrl_c_a_library_swallowed_still_writes_nothing(tmp_path, monkeypatch, capsys):
    # the report's stars load through the swallowing library: the report is built, then its
    # commit refuses to put it in place
    load_stars = build._load_stars

    def swallowing_load(*args, **kwargs):
        _interrupt_and_swallow()
        return load_stars(*args, **kwargs)

    monkeypatch.setattr(build, "_load_stars", swallowing_load)
    monkeypatch.setattr(build, "SECTION_BUILDERS", [])
    code = main(["report", "--out", str(tmp_path / "r")])
    assert code == 130 and capsys.readouterr().err.strip() == LINE
    assert list(tmp_path.iterdir()) == []  # no report, no staging folder


def test_ctrl_c_a_library_swallowed_ends_an_import_before_its_cluster(
    tmp_path, monkeypatch, capsys
):
    # catalog import: the signal lands in its optional imports and is swallowed; the import
    # stops before it starts a cluster, writes nothing and says why it ended
    pytest.importorskip("hats_import")
    importer = importlib.import_module("starsense.scale.importer")
    started = []
    monkeypatch.setattr(importer, "require", _interrupt_and_swallow)
    monkeypatch.setattr(importer, "client_or_local", lambda *a, **k: started.append(1))
    source = tmp_path / "stars.csv"
    source.write_text("ra,dec,V\n10.0,20.0,5.0\n11.0,21.0,6.0\n")
    code = main(["catalog", "import", str(source), str(tmp_path / "hats")])
    assert code == 130 and capsys.readouterr().err.strip() == LINE
    assert started == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stars.csv"]


def test_ctrl_c_turned_into_a_user_error_is_still_ctrl_c(tmp_path, monkeypatch, capsys):
    # an optional import, interrupted, fails as "not installed": the signal ended the command
    from starsense.errors import InputError

    def interrupted_import(*args, **kwargs):
        try:
            _interrupt()
        except BaseException:
            raise InputError("deep catalogues need the optional dependency") from None

    monkeypatch.setattr(cli_app, "_load", interrupted_import)
    assert main(_argv("trade", tmp_path / "out")) == 130
    assert capsys.readouterr().err.strip() == LINE


def test_a_second_ctrl_c_does_not_cut_the_cleanup_short(tmp_path, monkeypatch, capsys):
    # Ctrl-C pressed again while the command unwinds is ignored until main returns
    def twice(*args, **kwargs):
        try:
            _interrupt()
        finally:
            os.kill(os.getpid(), signal.SIGINT)  # during the unwinding: ignored

    monkeypatch.setattr(cli_app, "_load", twice)
    assert main(_argv("trade", tmp_path / "out")) == 130
    assert capsys.readouterr().err.strip() == LINE


@pytest.mark.slow
@pytest.mark.parametrize("name", COMMANDS)
def test_ctrl_c_during_the_real_start_up(name, tmp_path):
    # the real command, Ctrl-C at a few moments of its start-up: exit 130, one line, nothing
    # written (the --out folder not made), no traceback
    cmd = [sys.executable, "-c", "from starsense.cli import console_main; console_main()"]
    for delay in (0.3, 0.8, 1.5):
        out = tmp_path / f"out{delay}"
        proc = subprocess.Popen(
            [*cmd, *_argv(name, out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        text = err.decode()
        assert proc.returncode == 130, (delay, proc.returncode, text)
        assert "Traceback" not in text and text.strip().splitlines()[-1] == LINE, text
        assert list(tmp_path.iterdir()) == [], (delay, list(tmp_path.iterdir()))


#: armed by the test below: the at-fork hook (registered once for the process) sends SIGINT
_ARMED: list[bool] = []


def _signal_in_the_fork_hook() -> None:
    if _ARMED:
        _ARMED.clear()
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)  # the handler runs here, inside the hook: Python swallows its unwind


os.register_at_fork(after_in_parent=_signal_in_the_fork_hook)


def test_ctrl_c_landing_in_an_at_fork_hook_still_ends_the_command(tmp_path, monkeypatch, capsys):
    # the sweep (bench/bad_input_sweep.py) sent a Ctrl-C to `trade` while its process pool
    # forked: the unwind was raised in logging's after-fork lock release, reported as
    # "Exception ignored" (a traceback) and lost; the trade ran to its end, exit 0
    real = cli_app._load

    def fork_then_load(where):
        _ARMED.append(True)
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child leaves at once
            os._exit(0)
        os.waitpid(pid, 0)
        return real(where)

    monkeypatch.setattr(cli_app, "_load", fork_then_load)
    code = main(_argv("trade", tmp_path / "out"))
    assert code == 130
    assert capsys.readouterr().err.strip() == LINE  # one line: no "Exception ignored" traceback
    assert list(tmp_path.iterdir()) == []
