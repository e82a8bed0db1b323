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


def _children() -> dict[int, str]:
    """This process's live child processes (zombies left out): pid -> command line."""
    import os

    me, out = str(os.getpid()), {}
    for name in os.listdir("/proc") if os.path.isdir("/proc") else []:
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as fh:
                    head, tail = fh.read().rsplit(") ", 1)
            except OSError:
                continue
            fields = tail.split()
            if fields[1] == me and fields[0] != "Z":
                try:
                    with open(f"/proc/{name}/cmdline", "rb") as fh:
                        what = fh.read().replace(b"\0", b" ").decode(errors="replace")[:160]
                except OSError:
                    what = head.split(" (", 1)[1]
                out[int(name)] = what.strip()
    return out


def pytest_configure(config):
    """Adopt the processes the tests' children leave behind (Linux: a child subreaper), so that
    the end of the run can find and end them."""
    import contextlib
    import ctypes

    pr_set_child_subreaper = 36
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_child_subreaper, 1, 0, 0, 0)


@pytest.fixture(autouse=True)
def _no_process_left(request):
    """Name a test that leaves a process running (its own or an orphan of its children's)."""
    import sys
    import time

    before = set(_children())
    yield
    left = {p: n for p, n in _children().items() if p not in before}
    if left:  # a moment for processes that are ending
        time.sleep(0.5)
        left = {p: n for p, n in _children().items() if p not in before}
    if left:
        print(f"\n{request.node.nodeid} leaves running: {left}", file=sys.__stderr__)


def pytest_unconfigure(config):
    """End what the tests left running, and never hang at the end of the run.

    The interpreter's exit joins every child of Python's multiprocessing, and one that never
    ends (a fork that inherited a test's held signals) had held CI to its time limit after the
    summary was printed. Each process left is named, then killed; after two minutes more the
    stacks of every thread are written and the run ends (status 1) instead of waiting.
    """
    import faulthandler
    import os
    import signal
    import sys

    left = _children()
    if left:
        said = ", ".join(f"process {p} ({n})" for p, n in left.items())
        print(f"\nthe test run leaves running: {said}; killed", file=sys.__stderr__)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        except OSError:
            pass
    faulthandler.dump_traceback_later(120, exit=True, file=sys.__stderr__)
