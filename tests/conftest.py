"""Shared fixtures: the shared material lives at ../shared beside the repository."""

from __future__ import annotations

from pathlib import Path

import pytest

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
