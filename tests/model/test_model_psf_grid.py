"""A PSF on grids of whole pixels (``PixelPSF.grid``): the compiled kernel, the NumPy form, the
pointwise form, and the cubic interpolant of an independent spline code (FITPACK's)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import RectBivariateSpline

import starsense.model.psf_table as psf_table
from starsense.model.psf import pixel_psf
from starsense.sensor.psf_spec import PSFSpec

KINDS = [
    PSFSpec(),
    PSFSpec(kind="moffat", moffat_beta=2.5),
    PSFSpec(kind="airy", airy_obscuration=0.3),
]


def _offsets(seed, n=200):
    rng = np.random.default_rng(seed)
    # grids starting far outside the profile, across it and at whole-pixel offsets (a phase of
    # exactly zero between nodes), some reaching past its edge; and stars at no position (not a
    # number, infinite): a table's grids are dark there, a Gaussian's closed form not a number
    x0 = np.concatenate([rng.uniform(-40.0, 5.0, n), np.arange(-12.0, 0.0), [np.nan, np.inf]])
    y0 = np.concatenate([rng.uniform(-40.0, 5.0, n), np.arange(-6.0, 6.0), [0.0, -np.inf]])
    return x0, y0


@pytest.mark.parametrize("spec", KINDS, ids=lambda s: s.describe())
@pytest.mark.parametrize("gradient", [True, False])
def test_grid_is_the_pointwise_form(spec, gradient):
    # the same spline (or the Gaussian's closed form) at the same offsets: equal to rounding
    # (1e-12 of the peak: sums of 16 products in another order, and x0 + j rounded once)
    psf = pixel_psf(spec, 1.3)
    x0, y0 = _offsets(1)
    shape = (9, 14)
    got = psf.grid(x0, y0, shape, gradient=gradient)
    cols, rows = np.meshgrid(np.arange(shape[1]), np.arange(shape[0]))
    want = psf.evaluate(x0[:, None, None] + cols, y0[:, None, None] + rows, gradient=gradient)
    got, want = (got, want) if gradient else ((got,), (want,))
    peak = float(np.nanmax(np.abs(want[0])))
    for g, w in zip(got, want, strict=True):
        assert g.shape == (len(x0), *shape)
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-12 * peak)


@pytest.mark.skipif(psf_table._modelc is None, reason="the compiled model kernel is not built")
@pytest.mark.parametrize("spec", KINDS[1:], ids=lambda s: s.describe())
def test_compiled_grid_is_the_numpy_form(spec):
    psf = pixel_psf(spec, 0.9)
    x0, y0 = _offsets(2)
    shape = (11, 7)
    compiled = psf.grid(x0, y0, shape)
    table = psf._table
    outs = [np.zeros((len(x0), *shape)) for _ in range(3)]
    table._grid_numpy(x0, y0, outs, True)
    peak = float(np.max(outs[0]))
    for c, n in zip(compiled, outs, strict=True):
        np.testing.assert_allclose(c, n, rtol=0, atol=1e-12 * peak)  # the same sums, reordered


@pytest.mark.parametrize("spec", KINDS[1:], ids=lambda s: s.describe())
def test_spline_is_a_cubic_interpolant_of_the_table(spec):
    # the table's node values, interpolated by FITPACK's cubic spline (another end condition,
    # another basis): two cubic interpolants of one smooth table differ by the fourth-order
    # error of either, ~h^4 f'''' (h = 1/8 px): below 1e-5 of the peak for profiles of
    # FWHM >= 1.4 px, and their gradients below 1e-3 of the largest gradient
    psf = pixel_psf(spec, 1.0)
    r, per_px = psf._table.radius, psf._table.per_px
    nodes = np.linspace(-r, r, round(2 * r * per_px) + 1)
    at_nodes = psf.evaluate(nodes[None, :], nodes[:, None], gradient=False)
    fitpack = RectBivariateSpline(nodes, nodes, at_nodes, kx=3, ky=3)
    rng = np.random.default_rng(3)
    dx, dy = rng.uniform(-6.0, 6.0, 5000), rng.uniform(-6.0, 6.0, 5000)
    v, gx, gy = psf.evaluate(dx, dy)
    peak = float(at_nodes.max())
    np.testing.assert_allclose(v, np.maximum(fitpack.ev(dy, dx), 0.0), rtol=0, atol=1e-5 * peak)
    gmax = float(np.max(np.abs(gx)))
    np.testing.assert_allclose(gx, fitpack.ev(dy, dx, dy=1), rtol=0, atol=1e-3 * gmax)
    np.testing.assert_allclose(gy, fitpack.ev(dy, dx, dx=1), rtol=0, atol=1e-3 * gmax)
