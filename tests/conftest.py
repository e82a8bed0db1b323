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
