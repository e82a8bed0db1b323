"""Synthetic catalogues for the report tests (no real catalogue needed)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest


def synthetic_catalog(n: int = 1500, seed: int = 1, min_abs_dec_deg: float = 0.0):
    """A Catalog-like object: random directions, V in [-1, 9], B-V and V-I, a few NaNs."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    if min_abs_dec_deg > 0:
        keep = np.abs(v[:, 2]) >= np.sin(np.radians(min_abs_dec_deg))
        v = v[keep]
        n = len(v)
    mag_v = rng.uniform(-1.0, 9.0, n)
    b_v = rng.uniform(-0.2, 1.8, n)
    v_i = 1.1 * b_v + rng.normal(0, 0.05, n)
    b_v[:3] = np.nan  # skipped by the black-body fit
    return SimpleNamespace(
        name="synthetic",
        vectors=v,
        mags={"V": mag_v, "Hp": mag_v + 0.1},
        colours={"B-V": b_v, "V-I": v_i},
        extra={},
    )


class FakeCatalog(SimpleNamespace):
    def __len__(self) -> int:
        return len(self.vectors)


def make_catalog(**kwargs) -> FakeCatalog:
    ns = synthetic_catalog(**kwargs)
    return FakeCatalog(
        name=ns.name, vectors=ns.vectors, mags=ns.mags, colours=ns.colours, extra=ns.extra
    )


@pytest.fixture(scope="session")
def fake_catalog() -> FakeCatalog:
    return make_catalog()


@pytest.fixture(scope="session")
def catalog_factory():
    """make_catalog(n=..., seed=...) for tests that need their own catalogue."""
    return make_catalog
