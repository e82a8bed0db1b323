"""The independent renderer (tests/_support/galsim_frames.py) against physics and our renderer.

GalSim draws the pixels; these tests check that what it draws is the sky starsense describes
(flux, positions) and, for the Gaussian PSF, that starsense's own renderer draws the same
expected electrons (the check of our renderer by one nobody here wrote).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.special import j0, j1

galsim = pytest.importorskip("galsim", reason="galsim (the dev extra) draws these frames")

from galsim_frames import (  # noqa: E402
    FWHM_PER_SIGMA,
    PSF_KINDS,
    SHOOT_BELOW_E,
    galsim_frame,
    read_out,
    stamp_radius_px,
)
from zoo_trials import zoo  # noqa: E402

from starsense.catalog.table import Catalog  # noqa: E402
from starsense.geometry.attitude import attitude_from_radec_roll  # noqa: E402
from starsense.photometry.sensitivity import Sensitivity  # noqa: E402
from starsense.render.scene import render_frame  # noqa: E402
from starsense.units import DEG  # noqa: E402

#: a 640 x 480 crop of an IMX296-class camera: 3.45 um pixels behind 16 mm f/1.4, 100 ms
SENSOR = zoo.make_sensor(
    "imx296_crop", focal_length_m=0.016, columns=640, rows=480, pitch_um=3.45,
    psf_sigma_px=1.1, exposure_s=0.1, bit_depth=12, read_noise_e=2.2, qe=0.6, f_number=1.4,
)  # fmt: skip
ATTITUDE = attitude_from_radec_roll(84.0 * DEG, -1.0 * DEG, 0.4)  # Orion's belt: bright stars
RATE = np.array([0.6, -0.8, 0.0]) * DEG  # 1 deg/s across the boresight


def _catalog_at(sensor, attitude, xy, mags) -> Catalog:
    """A catalogue of stars that the attitude puts at pixel positions ``xy`` (N, 2)."""
    xy = np.asarray(xy, dtype=float)
    v = attitude.inv().apply(sensor.unproject(xy[:, 0], xy[:, 1]))
    return Catalog(
        name="synthetic",
        source="test",
        epoch_yr=2000.0,
        ids=np.arange(1, len(xy) + 1, dtype=np.int64),
        ra_rad=np.mod(np.arctan2(v[:, 1], v[:, 0]), 2 * math.pi),
        dec_rad=np.arcsin(np.clip(v[:, 2], -1, 1)),
        mags={"V": np.asarray(mags, dtype=float)},
    )


#: ten stars of V 2-6.5 well inside the 640 x 480 detector, at assorted sub-pixel phases
XY = np.column_stack([np.linspace(90.3, 540.7, 10), np.linspace(80.8, 400.15, 10)[::-1]])
MAGS = np.linspace(2.0, 6.5, 10)


@pytest.mark.parametrize(("psf", "rate"), [("gaussian", 0), ("moffat", 0), ("gaussian", 1)])
def test_flux_is_conserved(psf, rate) -> None:
    """Stamps wholly on the detector hold every electron of their star (Gaussian, Moffat).

    The Gaussian's stamp leaves out < 1e-7 of its light, the Moffat's 2e-4 (its encircled
    energy at the stamp's radius), the track's box nothing: 1e-3 is the brief's tolerance.
    """
    cat = _catalog_at(SENSOR, ATTITUDE, XY, MAGS)
    f = galsim_frame(SENSOR, ATTITUDE, psf=psf, rate_rad_s=RATE * rate, catalog=cat,
                     noise=False, keep_expected=True)  # fmt: skip
    stars = f.truth.stars
    assert len(stars) == 10 and stars.inside.all()
    electrons = Sensitivity.for_sensor(SENSOR, "reed").electrons(MAGS)  # independent of truth
    np.testing.assert_allclose(np.sort(stars.electrons), np.sort(electrons), rtol=1e-12)
    assert f.expected_e.sum() == pytest.approx(electrons.sum(), rel=1e-3)
    np.testing.assert_allclose(stars.electrons_drawn, stars.electrons, rtol=1e-3)


def test_airy_stamp_holds_its_encircled_energy() -> None:
    """An Airy stamp holds the light of the disc inside it: between the encircled energy of
    its inscribed and circumscribed circles, ``1 - J0(x)^2 - J1(x)^2`` at ``x = pi r D /
    lambda`` (Born & Wolf 8.5.2), with 1e-3 for the pixel's blur at the stamp's edge."""
    cat = _catalog_at(SENSOR, ATTITUDE, XY[4:5], MAGS[4:5])
    f = galsim_frame(SENSOR, ATTITUDE, psf="airy", catalog=cat, noise=False, keep_expected=True)
    fwhm = FWHM_PER_SIGMA * SENSOR.detector.psf_sigma_px
    lod = fwhm / 1.028993969962188  # the unobstructed Airy disc's FWHM is 1.029 lambda / D
    r = stamp_radius_px("airy", fwhm) + 0.5  # the stamp's half-width to its pixels' edges

    def ee(radius):
        x = math.pi * radius / lod
        return 1.0 - j0(x) ** 2 - j1(x) ** 2

    frac = f.expected_e.sum() / f.truth.stars.electrons[0]
    assert ee(r) - 1e-3 <= frac <= ee(math.sqrt(2.0) * r) + 1e-3
    assert frac < 0.995  # the far wings are not drawn: the docstring's ~1 %


@pytest.mark.parametrize("rate", [0, 1])
def test_gaussian_pixels_agree_with_starsense_renderer(rate) -> None:
    """GalSim's Gaussian convolved with the pixel (and the track's box) is starsense's
    expected image (exact erf products along the track) to 1e-4 of the brightest pixel:
    GalSim's k-space accuracy here is ~1e-7 of the peak, starsense's image is float32."""
    from starsense.catalog import load_catalog

    cat = load_catalog("hipparcos")
    ours = render_frame(SENSOR, ATTITUDE, cat, rate_rad_s=RATE * rate, noise=False)
    theirs = galsim_frame(SENSOR, ATTITUDE, rate_rad_s=RATE * rate, catalog=cat, noise=False,
                          keep_expected=True)  # fmt: skip
    peak = float(ours.expected_e.max())
    assert peak > 300.0  # bright stars in the field: the comparison means something
    diff = np.abs(theirs.expected_e - ours.expected_e.astype(np.float64))
    assert diff.max() <= 1e-4 * peak
    # the same stars, at the same mid-exposure positions
    a, b = ours.truth.stars, theirs.truth.stars
    common, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
    assert len(common) >= 0.95 * max(len(a), len(b))
    np.testing.assert_allclose(b.x_mid[ib], a.x_mid[ia], atol=1e-9)
    np.testing.assert_allclose(b.y_mid[ib], a.y_mid[ia], atol=1e-9)


@pytest.mark.parametrize("psf", PSF_KINDS)
def test_symmetric_psf_centroids_to_the_truth(psf) -> None:
    """The centre of mass of a noiseless star is its truth position, for every kind (the
    optical PSF's defocus and astigmatism are even: its image is point-symmetric).

    Tolerance: the stamp is centred on the nearest pixel, so its edge cuts up to half a pixel
    more wing on one side: < 1e-5 px of bias for the Gaussian, ~1e-4 px for the Moffat's
    2e-4 of light beyond it, ~2e-3 px for Airy and optical wings (~1 % beyond 16 FWHM).
    """
    xy = np.array([[300.3, 200.8]])
    cat = _catalog_at(SENSOR, ATTITUDE, xy, [4.0])
    f = galsim_frame(SENSOR, ATTITUDE, psf=psf, catalog=cat, noise=False, keep_expected=True)
    img = f.expected_e
    rows, cols = np.indices(img.shape)
    com = np.array([(img * cols).sum(), (img * rows).sum()]) / img.sum()
    truth = np.array([f.truth.stars.x_mid[0], f.truth.stars.y_mid[0]])
    np.testing.assert_allclose(truth, xy[0], atol=1e-6)  # project(unproject) round trip
    tol = {"gaussian": 1e-4, "moffat": 1e-3}.get(psf, 5e-3)
    np.testing.assert_allclose(com, truth, atol=tol)


def test_read_out_moments() -> None:
    """Counts of a flat 100 e- field: mean g e + bias, variance g^2 (e + r^2) + 1/12 (the
    rounding), both within 4 standard errors over 200,000 pixels; a saturated pixel reads the
    ADC's top."""
    det = dataclasses.replace(SENSOR.detector, bias_counts=100.0)
    e = np.full((400, 500), 100.0)
    c = read_out(e, det, exposure_s=0.1, rng=np.random.default_rng(5)).astype(float)
    g, r = det.gain_counts_per_e, det.read_noise_e
    var = g**2 * (100.0 + r**2) + 1.0 / 12.0
    n = e.size
    assert c.mean() == pytest.approx(g * 100.0 + 100.0, abs=4 * math.sqrt(var / n))
    assert c.var() == pytest.approx(var, rel=4 * math.sqrt(2.0 / n))
    top = read_out(np.full((2, 2), 1e9), det, exposure_s=0.1, rng=np.random.default_rng(1))
    assert g * det.full_well_e > 2**det.bit_depth  # the ADC saturates before the well
    assert top.dtype == np.uint16 and (top == 2**det.bit_depth - 1).all()


def test_shot_faint_stars_have_their_electrons_on_average() -> None:
    """Photon-shot stars (the fast path of noisy frames) put their expected electrons on the
    detector on average: 40 frames of ten V 6 stars (~350 e- each); the counts in 21 x 21 px
    boxes around them, less the bias, agree with the expected charge within 4 standard
    errors (Poisson and read noise over the boxes: 0.4 % of it)."""
    sensor = SENSOR.with_(detector=dataclasses.replace(SENSOR.detector, bias_counts=50.0))
    det = sensor.detector
    cat = _catalog_at(sensor, ATTITUDE, XY, np.full(10, 6.0))
    e = float(Sensitivity.for_sensor(sensor, "reed").electrons(6.0))
    assert 100.0 < e < SHOOT_BELOW_E  # photon-shot
    ix, iy = np.rint(XY).astype(int).T
    boxes = (iy[:, None, None] + np.arange(-10, 11)[None, :, None],
             ix[:, None, None] + np.arange(-10, 11)[None, None, :])  # fmt: skip
    npx, frames, total = 10 * 21 * 21, 40, 0.0
    rng = np.random.default_rng(11)
    for _ in range(frames):
        counts = galsim_frame(sensor, ATTITUDE, catalog=cat, seed=rng).image.astype(float)
        total += (counts[boxes].sum() - det.bias_counts * npx) / det.gain_counts_per_e
    sd = math.sqrt((10 * e + npx * det.read_noise_e**2) / frames)  # of the mean over frames
    assert total / frames == pytest.approx(10 * e, abs=4 * sd)


def test_bad_psf_and_unsupported_detector_are_refused() -> None:
    with pytest.raises(ValueError, match="unknown psf 'lorentz'"):
        galsim_frame(SENSOR, ATTITUDE, psf="lorentz", catalog=_catalog_at(SENSOR, ATTITUDE,
                     XY[:1], MAGS[:1]))  # fmt: skip
    hot = SENSOR.with_(detector=dataclasses.replace(SENSOR.detector, prnu_fraction=0.01))
    with pytest.raises(ValueError, match="prnu_fraction"):
        galsim_frame(hot, Rotation.identity())
