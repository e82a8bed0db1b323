"""The bad-input and fault sweep (bench/bad_input_sweep.py) in its fast form: every case clean.

The sweep draws its cases from a seed over every command of the app (bad values, special files
where outputs go, bad input files, usage errors, SIGINT / SIGTERM at a random moment, huge counts
and frames) and runs each in its own forked process, folder, process group and ``TMPDIR``. A
case is clean when it is refused in one line with exit 2 (or typer's usage message), ends
130 / 143 after a signal, prints no traceback, accepts nothing it must refuse, leaves no file
or process behind, replaces no FIFO, device, link or socket, and peaks under 2 GB resident.
The default run sweeps a fixed seed's 120 cases (about a minute); the slow run 1,000 cases of
another fixed seed. Fresh seeds, drawn at run time and printed, are `make bench-sweep`'s.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "bench" / "bad_input_sweep.py"
_spec = importlib.util.spec_from_file_location("starsense_bench_sweep", _PATH)
sweep_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sweep_module)

#: the slow form's seed (a fresh seed of `make bench-sweep` found five faults in it, fixed)
THOUSAND_SEED = 743908662
#: the fast form's seed (fixed: a CI run is reproducible) and size
FAST_SEED = 50
FAST_CASES = 120


def _assert_clean(record: dict) -> None:
    shown = json.dumps(record["failures"][:10], indent=1)
    assert record["clean"] == record["cases"], f"seed {record['seed']}: {shown}"
    assert record["peak_rss_mb_max"] < sweep_module.MAX_RSS_BYTES / 1e6


def _sweep(seed: int, cases: int, tmp_path: Path) -> dict:
    """The sweep as `make bench-sweep` runs it: its cases forked from a fresh interpreter that
    has imported every command (forked from this test run instead, each case would carry the
    run's threads and its resident pages, and its memory would be judged with them)."""
    out = tmp_path / "record.json"
    cmd = [sys.executable, str(_PATH), "--seed", str(seed), "--cases", str(cases), "--jobs", "2"]
    done = subprocess.run([*cmd, "--out", str(out)], capture_output=True, text=True, check=False)
    print(done.stdout[-4000:], done.stderr[-4000:])
    said = done.stderr[-2000:]
    assert out.is_file(), f"the sweep wrote no record (exit {done.returncode}): {said}"
    return json.loads(out.read_text())


def test_sweep_fast_form(tmp_path):
    record = _sweep(FAST_SEED, FAST_CASES, tmp_path)
    assert record["cases"] == FAST_CASES
    _assert_clean(record)
    # the fixed seed reaches each kind of case
    assert set(record["kinds"]) == {"value", "output", "input", "usage", "signal", "huge"}


@pytest.mark.slow
def test_sweep_of_a_thousand_cases(tmp_path):
    # a fixed seed: a CI run must be reproducible (a seed drawn at run time is `make
    # bench-sweep`'s, whose findings become cases of their own); this one found five faults
    # before they were fixed
    seed = THOUSAND_SEED
    record = _sweep(seed, 1000, tmp_path)
    _assert_clean(record)
    assert set(record["commands_swept"]) == set(record["commands"])
