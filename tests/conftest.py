"""Shared fixtures: the shared material lives at ../shared beside the repository."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings

# property tests draw their examples from a fixed search (the same on every run): a CI run is
# reproducible, and a counterexample found once is found again (a random search had turned a
# run red once in many on a one-point tie of a clipping boundary)
settings.register_profile("starsense", derandomize=True)
settings.load_profile("starsense")

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"shared material not found at {SHARED}")
    return SHARED


@pytest.fixture(scope="session")
def bsc5_path(shared_dir: Path) -> Path:
    path = shared_dir / "data" / "catalogs" / "bsc5"
    if not path.is_file():
        pytest.skip(f"BSC5 catalogue not found at {path}")
    return path


@pytest.fixture(autouse=True, scope="session")
def _isolated_cache(tmp_path_factory):
    """Keep the test run's catalogue cache out of the user's cache directory."""
    import os

    old = os.environ.get("STARSENSE_CACHE_DIR")
    os.environ["STARSENSE_CACHE_DIR"] = str(tmp_path_factory.mktemp("starsense-cache"))
    yield
    if old is None:
        os.environ.pop("STARSENSE_CACHE_DIR", None)
    else:
        os.environ["STARSENSE_CACHE_DIR"] = old


def _left_behind() -> list[str]:
    """What the test process still runs at its end: threads that hold its exit, child processes."""
    import os
    import threading

    out = [f"thread {t.name!r}" for t in threading.enumerate() if not t.daemon and t.is_alive()]
    out = [o for o in out if o != "thread 'MainThread'"]
    me = str(os.getpid())
    for name in os.listdir("/proc") if os.path.isdir("/proc") else []:
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as fh:
                    head, tail = fh.read().rsplit(") ", 1)
            except OSError:
                continue
            fields = tail.split()
            if fields[1] == me and fields[0] != "Z":
                out.append(f"process {name} ({head.split(' (', 1)[1]})")
    return out


def pytest_unconfigure(config):
    """Say what is left running at the end of the run, and never hang there.

    A run that printed its summary and then waited on a thread or a process it had left behind
    had held CI to its time limit; now it names them, and after two minutes the stacks of every
    thread are written and the run ends (status 1) instead of waiting.
    """
    import faulthandler
    import sys

    left = _left_behind()
    if left:
        print(f"\nthe test run leaves running: {', '.join(left)}", file=sys.stderr)
    faulthandler.dump_traceback_later(120, exit=True, file=sys.__stderr__)
