"""The forward model's expected pixels and their Jacobian; the fit on frames it did not draw."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.geometry.attitude import small_rotation_angles
from starsense.model.fit import fit_windows
from starsense.model.psf import pixel_psf
from starsense.model.tracks import node_positions, time_nodes
from starsense.model.windows import evaluate, make_windows
from starsense.sensor import load_sensor
from starsense.sensor.psf_spec import PSFSpec


def _scene(n=12, seed=2):
    """A small camera and n stars spread over its field (ICRS = camera frame at identity)."""
    sensor = load_sensor("esa_blackfly")
    rng = np.random.default_rng(seed)
    x = rng.uniform(40, sensor.detector.columns - 40, n)
    y = rng.uniform(40, sensor.detector.rows - 40, n)
    v = sensor.unproject(x, y)
    return sensor, v


def _mu(sensor, psf, v, rot, rate, fluxes, windows, kept, free, frac, wts, fit_rate):
    nodes = node_positions(
        sensor, v[kept], rot, rate_rad_s=rate, exposure_s=sensor.exposure_s, fractions=frac,
        weights=wts,
        fit_rate=fit_rate,
    )  # fmt: skip
    ev = evaluate(windows, psf, nodes, fluxes=fluxes)
    return ev


@pytest.mark.parametrize("kind", ["gaussian", "moffat"])
@pytest.mark.parametrize("rate_deg_s", [0.0, 1.0])
def test_jacobian_is_the_derivative_of_the_pixels(kind, rate_deg_s):
    """d mu / d (theta, w) against central differences of the whole model (attitude, rate).

    Steps of 3e-7 rad (0.1 px at this focal length of ~2,000 px... over the rate, the same turn
    over the exposure): the differences' truncation error, ~h^2 mu''' / 6, and the Jacobian's
    own (its node positions are differenced at 1e-6 rad) stay below 1e-4 of the largest entry.
    """
    sensor, v = _scene()
    psf = pixel_psf(PSFSpec(kind=kind), sensor.detector.psf_sigma_px)
    rot = Rotation.identity()
    rate = np.radians([rate_deg_s, -0.6 * rate_deg_s, 0.3 * rate_deg_s])
    fit_rate = rate_deg_s > 0
    frac, wts = time_nodes(30.0 if fit_rate else 0.0, psf.sigma_px)
    free = np.ones(len(v), bool)
    nodes = node_positions(
        sensor, v, rot, rate_rad_s=rate, exposure_s=sensor.exposure_s, fractions=frac, weights=wts
    )
    windows, kept = make_windows(nodes.x, nodes.y, half_px=5.0, shape=(1000, 1000), free=free)
    fluxes = np.linspace(1e3, 5e4, len(kept))
    args = (windows, kept, free[kept], frac, wts, fit_rate)
    ev = _mu(sensor, psf, v, rot, rate, fluxes, *args)
    jac = ev.jacobian
    h = 3e-7
    n_par = 6 if fit_rate else 3
    for p in range(n_par):
        step = np.zeros(6)
        step[p] = h if p < 3 else h / sensor.exposure_s
        mus = []
        for sign in (1, -1):
            r2 = Rotation.from_rotvec(sign * step[:3]) * rot
            e2 = _mu(sensor, psf, v, r2, rate + sign * step[3:], fluxes, *args)
            mus.append(np.einsum("gmhw,gm->ghw", e2.templates, _slots(windows, fluxes)))
        fd = (mus[0] - mus[1]) / (2 * (step[p]))
        assert np.abs(fd - jac[:, p]).max() < 1e-4 * np.abs(jac[:, p]).max()


def _slots(windows, fluxes):
    out = np.zeros((windows.n_groups, windows.n_slots))
    out[windows.group, windows.slot] = fluxes
    return out


def test_fit_recovers_the_attitude_of_a_noiseless_frame():
    """A frame drawn by the model itself at a known attitude is fitted back to it (1e-4 px)."""
    sensor, v = _scene(n=15, seed=4)
    psf = pixel_psf(sensor.psf, sensor.detector.psf_sigma_px)
    truth = Rotation.from_rotvec([2e-4, -1e-4, 5e-4])
    frac, wts = time_nodes(0.0, psf.sigma_px)
    free = np.ones(len(v), bool)
    nodes = node_positions(
        sensor, v, truth, rate_rad_s=np.zeros(3), exposure_s=sensor.exposure_s,
        fractions=frac, weights=wts,
    )  # fmt: skip
    det = sensor.detector
    windows, kept = make_windows(nodes.x, nodes.y, half_px=8.0, shape=(det.rows, det.columns),
                                 free=free)  # fmt: skip
    fluxes = np.geomspace(2e3, 2e4, len(kept))
    ev = evaluate(windows, psf, nodes, fluxes=fluxes, gradient=False)
    image = np.full((det.rows, det.columns), 50.0)  # a background of 50 e-
    light = np.einsum("gmhw,gm->ghw", ev.templates, _slots(windows, fluxes))
    for g in range(windows.n_groups):
        r0, c0 = windows.row0[g], windows.col0[g]
        h, w = windows.shape
        rr, cc = (
            slice(max(r0, 0), min(r0 + h, det.rows)),
            slice(max(c0, 0), min(c0 + w, det.columns)),
        )
        image[rr, cc] += light[g, rr.start - r0 : rr.stop - r0, cc.start - c0 : cc.stop - c0]
    counts = image * det.gain_counts_per_e + det.bias_counts
    start = Rotation.from_rotvec([0.0, 0.0, 3e-4]) * truth  # ~0.6 px off at the corners
    fit = fit_windows(counts, sensor, start, vectors=v[kept])
    err = small_rotation_angles(fit.rotation, truth) * sensor.focal_length_px
    assert fit.converged
    assert np.abs(err).max() < 1e-4
    np.testing.assert_allclose(fit.fluxes_e, fluxes, rtol=1e-6)
