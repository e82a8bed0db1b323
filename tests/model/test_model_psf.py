"""The pixel-integrated PSFs of the forward model: flux, gradient, symmetry, and GalSim's pixels."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from starsense.model.psf import pixel_psf
from starsense.render.psf import pixel_profile
from starsense.sensor.psf_spec import FWHM_PER_SIGMA, PSFSpec

KINDS = [
    PSFSpec(),
    PSFSpec(kind="moffat", moffat_beta=2.5),
    PSFSpec(kind="moffat", moffat_beta=4.0),
    PSFSpec(kind="airy"),
    PSFSpec(kind="airy", airy_obscuration=0.3),
]


def _grid(psf, x0, y0, half=40):
    g = np.arange(-half, half + 1)
    cols, rows = np.meshgrid(g, g)
    return psf.evaluate(cols - x0, rows - y0)


@pytest.mark.parametrize("spec", KINDS, ids=lambda s: s.describe())
@pytest.mark.parametrize("sigma", [0.6, 1.1, 2.3])
def test_flux_is_what_the_profile_holds(spec, sigma):
    """Summed over the pixels, the light is 1 less what lies beyond the table's radius.

    The table's box integral and the midpoint sums agree to ~1e-5 (module docstring of psf.py);
    2e-4 allows the spline's error summed over the ~(2 r)^2 pixels, and a tenth of the light
    outside the table the pixels straddling its edge (half a pixel of a slowly falling wing).
    """
    psf = pixel_psf(spec, sigma)
    v, _, _ = _grid(psf, 0.3, -0.2)
    tol = 2e-4 + 0.1 * psf.outside_fraction
    assert v.sum() == pytest.approx(1.0 - psf.outside_fraction, abs=tol)
    assert psf.outside_fraction < 0.05


@pytest.mark.parametrize("spec", KINDS, ids=lambda s: s.describe())
def test_gradient_is_the_derivative(spec):
    """The analytic (Gaussian) and spline (others) gradients against central differences.

    h = 1e-4 px: the difference's truncation error, ~h^2 f''' / 6, is below 1e-8 of the peak.
    """
    psf = pixel_psf(spec, 1.1)
    rng = np.random.default_rng(3)
    dx, dy = rng.uniform(-5, 5, 400), rng.uniform(-5, 5, 400)
    v, gx, gy = psf.evaluate(dx, dy)
    h = 1e-4
    fx = (
        (psf.evaluate(dx + h, dy, gradient=False) - psf.evaluate(dx - h, dy, gradient=False))
        / 2
        / h
    )
    fy = (
        (psf.evaluate(dx, dy + h, gradient=False) - psf.evaluate(dx, dy - h, gradient=False))
        / 2
        / h
    )
    peak = v.max()
    assert np.abs(fx - gx).max() < 1e-6 * peak
    assert np.abs(fy - gy).max() < 1e-6 * peak


@pytest.mark.parametrize("spec", KINDS, ids=lambda s: s.describe())
def test_profile_is_circular(spec):
    """A circular PSF: the same light at (dx, dy), (-dx, -dy), (dy, dx) (the table's symmetry).

    The spline of a symmetric table on a symmetric grid is symmetric to rounding: 1e-12.
    """
    psf = pixel_psf(spec, 1.3)
    rng = np.random.default_rng(5)
    dx, dy = rng.uniform(-6, 6, 300), rng.uniform(-6, 6, 300)
    v = psf.evaluate(dx, dy, gradient=False)
    assert np.abs(v - psf.evaluate(-dx, -dy, gradient=False)).max() < 1e-12
    assert np.abs(v - psf.evaluate(dy, dx, gradient=False)).max() < 1e-12


@pytest.mark.parametrize("spec", KINDS[:3], ids=lambda s: s.describe())
def test_symmetric_profile_centroids_to_its_centre(spec):
    """A symmetric PSF's pixel centre of gravity is the star's position (an invariant).

    Gaussian and Moffat: their light beyond the table (< 1e-3) pulls by < 1e-3 px. (The Airy's
    wing, 2 % beyond the table, is cut by the pixel lattice unevenly: not an invariant there.)
    """
    psf = pixel_psf(spec, 1.3)
    g = np.arange(-40, 41)
    cols, rows = np.meshgrid(g, g)
    for x0, y0 in [(0.0, 0.0), (0.37, -0.21), (-0.5, 0.49)]:
        v = psf.evaluate(cols - x0, rows - y0, gradient=False)
        assert (v * cols).sum() / v.sum() == pytest.approx(x0, abs=1e-3)
        assert (v * rows).sum() / v.sum() == pytest.approx(y0, abs=1e-3)


def test_gaussian_is_the_renderers_exact_profile():
    """The model's Gaussian equals the renderer's erf products (render.psf.pixel_profile)."""
    psf = pixel_psf(PSFSpec(), 0.9)
    x0, y0 = 10.3, -4.6
    px = pixel_profile(0, 21, [x0], sigma_px=0.9)[0]
    py = pixel_profile(-15, 6, [y0], sigma_px=0.9)[0]
    cols, rows = np.meshgrid(np.arange(0, 21), np.arange(-15, 6))
    v = psf.evaluate(cols - x0, rows - y0, gradient=False)
    assert np.abs(v - np.outer(py, px)).max() < 1e-14


galsim = pytest.importorskip("galsim", reason="GalSim (the dev extra) draws the reference pixels")


@pytest.mark.parametrize("spec", KINDS[1:], ids=lambda s: s.describe())
@pytest.mark.parametrize("sigma", [0.7, 1.1, 2.0])
def test_pixels_agree_with_galsim(spec, sigma):
    """GalSim's Moffat and Airy of the same FWHM, drawn with its pixel response, are ours.

    GalSim (an independent implementation: Fourier-space convolution with the pixel) draws at
    its default accuracy (folding_threshold 5e-3, maxk_threshold 1e-3): the pixels agree to
    ~1e-3 of the peak. Our table stops at ``radius_px``; GalSim's profile does not, so the
    comparison is of the light within our radius.
    """
    fwhm = FWHM_PER_SIGMA * sigma
    if spec.kind == "moffat":
        prof = galsim.Moffat(beta=spec.moffat_beta, fwhm=fwhm)
    else:  # GalSim's own profile's half maximum, found on its xValue (its FWHM: e = 0 only)
        unit = galsim.Airy(lam_over_diam=1.0, obscuration=spec.airy_obscuration)
        peak = unit.xValue(galsim.PositionD(0, 0))
        r_half = brentq(lambda r: unit.xValue(galsim.PositionD(r, 0)) - 0.5 * peak, 1e-3, 1.0)
        prof = galsim.Airy(lam_over_diam=fwhm / (2 * r_half), obscuration=spec.airy_obscuration)
    n = 31
    offset = (0.31, -0.18)
    img = prof.drawImage(nx=n, ny=n, scale=1.0, offset=offset).array
    psf = pixel_psf(spec, sigma)
    g = np.arange(n) - (n - 1) / 2
    cols, rows = np.meshgrid(g, g)
    ours = psf.evaluate(cols - offset[0], rows - offset[1], gradient=False)
    assert np.abs(ours - img).max() < 2e-3 * img.max()
