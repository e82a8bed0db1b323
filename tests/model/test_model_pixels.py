"""A pixel's likelihood at the ADC's floor: the censored information, and the fit that uses it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from model_scene import model_image
from scipy import integrate
from scipy.spatial.transform import Rotation
from scipy.stats import norm

from starsense.geometry.attitude import small_rotation_angles
from starsense.model.fit import fit_windows
from starsense.model.pixels import censored_information, floor_e, pixel_terms
from starsense.sensor import load_sensor


@pytest.mark.parametrize("a", [-6.0, -2.0, -0.5, 0.0, 0.7, 2.0, 4.0])
def test_censored_information_is_the_tobit_fisher_information(a):
    """kappa(a) against the expectation of the squared score, integrated by quadrature.

    A unit normal about mu = 0 censored below ``a``: the score on mu is ``-phi(a) / Phi(a)``
    when censored (probability Phi(a)), ``y`` above; its second moment is the information.
    quad's error is ~1e-10; 1e-8 is the tolerance.
    """
    above, _ = integrate.quad(lambda y: y * y * norm.pdf(y), a, np.inf)
    censored = norm.pdf(a) ** 2 / norm.cdf(a)
    assert censored_information(a) == pytest.approx(above + censored, abs=1e-8)


def test_pixel_terms_at_the_floor_have_unit_mean_chi_square_and_zero_mean_score():
    """Drawn from the model and read through a floor at zero: each term's expectation.

    The chi-square terms average 1 and the scores (residual x weight) 0, over 400,000 pixels
    about a mean near the floor (their sd ~1.5 / sqrt(n) ~ 0.002: tolerances of 0.01).
    """
    det = load_sensor("esa_blackfly").detector
    det = dataclasses.replace(det, bias_counts=0.0, gain_counts_per_e=1.0, read_noise_e=3.0)
    rng = np.random.default_rng(1)
    mu = np.full(400_000, 1.5)
    v = mu + 9.0 + 1.0 / 12.0
    value = mu + rng.standard_normal(mu.size) * np.sqrt(v)
    data = np.where(value < floor_e(det, 0.0), -0.0, value)  # read as 0 counts: the floor
    weight, resid, chi2 = pixel_terms(det, mu, data, use=np.ones(mu.size, bool), exposure_s=0.0)
    assert float(np.mean(chi2)) == pytest.approx(1.0, abs=0.01)
    assert float(np.mean(weight * resid) * np.sqrt(v[0])) == pytest.approx(0.0, abs=0.01)


def _zero_bias_scene(seed):
    """A camera whose bias is zero (dark pixels read 0 half the time) and 15 faint stars."""
    sensor = load_sensor("esa_blackfly")
    det = dataclasses.replace(sensor.detector, bias_counts=0.0)
    sensor = sensor.with_(detector=det)
    rng = np.random.default_rng(seed)
    x = rng.uniform(40, det.columns - 40, 15)
    y = rng.uniform(40, det.rows - 40, 15)
    return sensor, sensor.unproject(x, y)


def test_a_fit_through_the_floor_is_honest_and_its_chi_square_is_one():
    """Frames drawn by the model and read through the ADC's floor at zero, 60 noise draws.

    The stars are faint (300-3,000 e-) on no sky: half of each window reads 0. Each fit's
    reduced chi-square is 1 within 5 of its sigma, sqrt(2 / dof), and every fit converges; the
    attitude errors over the reported sigmas, pooled over 60 frames x 3 axes, have an rms of 1
    within 0.15 (3 sd of an rms of 180 normal draws, 1 / sqrt(360) ~ 0.053). A fit that leaves
    the zeros out reads a chi-square of ~0.5; one that reads them as values, a biased background.
    """
    sensor, v = _zero_bias_scene(3)
    det = sensor.detector
    truth = Rotation.from_rotvec([1e-4, -2e-4, 3e-4])
    expected, kept, fluxes = model_image(sensor, v, truth, (300.0, 3000.0))
    rng = np.random.default_rng(11)
    z = []
    sd = np.sqrt(expected + det.read_noise_e**2)
    for _ in range(60):
        e = expected + rng.standard_normal(expected.shape) * sd
        counts = np.clip(np.round(e * det.gain_counts_per_e), 0, None)  # the ADC's floor
        fit = fit_windows(counts, sensor, truth, vectors=v[kept], fluxes_e=fluxes)
        assert fit.converged  # the censored likelihood's fluxes settle slowly; the fit stops
        assert abs(fit.reduced_chi2 - 1.0) < 5.0 * math.sqrt(2.0 / fit.dof)
        err = small_rotation_angles(truth, fit.rotation)
        z.append(err / np.sqrt(np.diag(fit.covariance)[:3]))
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert rms == pytest.approx(1.0, abs=0.15)


def test_a_star_past_the_full_well_everywhere_holds_no_position_information():
    # an undersampled Airy star (sigma 0.5 px) of 1e7 electrons on a 1,000-electron well: every
    # pixel of its window is past the well (no weight), its flux and the background cannot be
    # told apart and its position is unknown (information 0, sigma infinite), not an error;
    # a star within the well keeps its information
    from starsense.model.fisher import position_information, position_sigma_px
    from starsense.sensor.psf_spec import PSFSpec

    base = load_sensor("st16")
    det = dataclasses.replace(base.detector, full_well_e=1000.0, psf_sigma_px=0.5)
    sensor = base.with_(detector=det, psf=PSFSpec(kind="airy"))
    electrons = [500.0, 1e7]
    info = position_information(sensor, electrons)
    assert np.all(np.isfinite(info))
    assert info[0, 0, 0] > 0 and info[0, 1, 1] > 0
    np.testing.assert_array_equal(info[1], 0.0)
    sigma = position_sigma_px(sensor, electrons)
    assert math.isfinite(sigma[0]) and sigma[1] == math.inf
