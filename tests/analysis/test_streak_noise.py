"""The datasheet's NEA under slew: a smeared star's centroid error, derived from its pixels,
against the solver's own streak centroid on rendered noisy streaks; the anisotropic
propagation through the attitude fit."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from starsense.analysis.datasheet.field import (
    FieldStarsCam,
    propagated_covariance,
    propagated_sigmas,
)
from starsense.analysis.datasheet.streak_noise import blend_cov_px2, is_streaked, streak_errors
from starsense.detect.streak import SYSTEMATIC, streak_centroids
from starsense.render.noise import apply_noise
from starsense.render.smear import streak_stamp_expected
from starsense.sensor import load_sensor
from starsense.solve.streaks import CAPSULE_PAD_PX, CAPSULE_SIGMAS, streak_centroids_of

#: noisy renders per case: the sample standard deviation of K Gaussian draws has a relative
#: standard error of 1 / sqrt(2 (K - 1)) = 2.9 % at K = 600; the tolerance is 3.5 of those
#: (10 %), and the linearised model's own error (the window moves with the noise, second order
#: in the noise) is well below it for stars of a few hundred electrons per PSF length and more
_K = 600
_REL = 3.5 / math.sqrt(2.0 * (_K - 1))


def _sensor(**det):
    s = load_sensor("st16")
    return dataclasses.replace(s, detector=dataclasses.replace(s.detector, **det))


def _rendered(sensor, n_e, centre, streak, rng):
    """Errors (K, 2) of the solver's capsule centroid over K noisy renders of one streak, px."""
    det = sensor.detector
    radius = CAPSULE_SIGMAS * det.psf_sigma_px + CAPSULE_PAD_PX
    cx, cy = centre
    half = math.ceil(0.5 * float(np.max(np.abs(streak))) + radius + 8)
    r0, c0 = math.floor(cy) - half, math.floor(cx) - half
    size = 2 * half + 1
    stamp, sr, sc = streak_stamp_expected(
        sensor,
        x0=cx - streak[0] / 2,
        y0=cy - streak[1] / 2,
        x1=cx + streak[0] / 2,
        y1=cy + streak[1] / 2,
        electrons=n_e,
    )
    expected = np.zeros((size, size))
    expected[sr - r0 : sr - r0 + stamp.shape[0], sc - c0 : sc - c0 + stamp.shape[1]] = stamp
    frames = np.broadcast_to(expected, (_K, size, size)).copy()
    counts = apply_noise(frames, sensor, rng=rng).astype(float) - det.bias_counts
    gx, gy, _, _, _ = streak_centroids(
        counts,
        np.full(_K, cx - c0),
        np.full(_K, cy - r0),
        streaks=np.tile(np.asarray(streak) * (1.0 + SYSTEMATIC), (_K, 1)),
        radius=radius,
    )
    return np.column_stack([gx + c0 - cx, gy + r0 - cy])


@pytest.mark.parametrize(
    ("det", "n_e", "length"),
    [
        # undersampled, 14-bit, no bias: the ADC clips the background's noise at 0 and leaves
        # a pedestal in every pixel of the capsule
        ({"psf_sigma_px": 0.6, "read_noise_e": 2.0, "gain_counts_per_e": 1.4}, 1.0e4, 21.0),
        # wide PSF, strong read noise, a short streak
        ({"psf_sigma_px": 2.0, "read_noise_e": 15.0, "bias_counts": 100.0}, 3.0e4, 9.0),
        # bright: the streak's middle saturates the 12-bit ADC
        ({"psf_sigma_px": 0.8, "read_noise_e": 3.5, "gain_counts_per_e": 0.5}, 2.0e5, 15.0),
    ],
)
def test_streak_centroid_noise_against_rendered_streaks(det, n_e, length):
    sensor = _sensor(**det)
    rng = np.random.default_rng(11)
    streak = length * np.array([math.cos(0.6), math.sin(0.6)])
    centre = (400.3, 300.7)
    err = _rendered(sensor, n_e, centre, streak, rng)
    assert np.isfinite(err).all()
    pred = streak_errors(sensor, [n_e], [centre], streaks_px=[streak])
    u = streak / np.hypot(*streak)
    v = np.array([-u[1], u[0]])
    cov = pred.cov_px2[0]
    for axis in (u, v):  # along and across the streak
        assert np.std(err @ axis) == pytest.approx(math.sqrt(axis @ cov @ axis), rel=_REL)
    # along it the star's own light spans the streak: (sigma^2 + l^2 / 12) against sigma^2,
    # at least 1.6x apart in these cases (the shortest: sqrt(4 + 6.75) / 2)
    assert math.sqrt(u @ cov @ u) > 1.5 * math.sqrt(v @ cov @ v)
    # a whole streak's centroid is unbiased: the model's bias within the mean's noise
    sem = np.std(err, axis=0) / math.sqrt(_K)
    assert np.all(np.abs(pred.bias_px[0]) < 4 * sem + 0.005)


def test_streak_cut_by_the_frame_edge_is_pulled_inwards():
    sensor = _sensor(psf_sigma_px=1.0, read_noise_e=3.0, bias_counts=50.0)
    rng = np.random.default_rng(5)
    streak = np.array([30.0, 0.0])
    centre = (8.0, 300.0)  # a third of the streak runs off the left edge (column < -0.5)
    pred = streak_errors(sensor, [5.0e4], [centre], streaks_px=[streak])
    # the pixels off the frame hold nothing: render, then zero the columns left of the frame
    err = _rendered_cut(sensor, 5.0e4, centre, streak, rng)
    sem = np.std(err, axis=0) / math.sqrt(len(err))
    # the pull is ~ a third of the streak's half (5 px): the model's within 4 sem + 2 %
    assert pred.bias_px[0, 0] > 3.0
    assert abs(np.mean(err[:, 0]) - pred.bias_px[0, 0]) < 4 * sem[0] + 0.02 * pred.bias_px[0, 0]
    # the solver treats it as a point anywhere along its streak: l l^T / 12
    assert pred.solver_cov_px2[0, 0, 0] == pytest.approx(streak[0] ** 2 / 12.0)


def test_a_clipped_streak_is_weighted_as_the_solver_weights_it():
    # the 12-bit ADC clips the ridge of 2e6 e- streaks: the solver gives each the error of a
    # clipped streak over its pixel phase (solve.streak_bias) on top of its photon noise, and
    # the prediction must weight them alike, or their biases count many times in the attitude
    sensor = _sensor(psf_sigma_px=0.8, read_noise_e=3.5, gain_counts_per_e=0.5, bias_counts=20)
    det = sensor.detector
    n_e = 2.0e6
    streak = 25.0 * np.array([math.cos(0.4), math.sin(0.4)])
    # three parallel streaks near the middle of the frame (the solver fits the rate to >= 3)
    offsets = np.array([[0.3, 0.6], [-60.7, 50.2], [70.4, 40.9]])
    centres = np.array([det.columns / 2, det.rows / 2]) + offsets
    image = np.zeros((det.rows, det.columns))
    for c in centres:
        stamp, sr, sc = streak_stamp_expected(
            sensor, x0=c[0] - streak[0] / 2, y0=c[1] - streak[1] / 2,
            x1=c[0] + streak[0] / 2, y1=c[1] + streak[1] / 2, electrons=n_e,
        )  # fmt: skip
        image[sr : sr + stamp.shape[0], sc : sc + stamp.shape[1]] += stamp
    image = apply_noise(image, sensor, rng=np.random.default_rng(3))
    got = streak_centroids_of(
        sensor, image, centres + 0.4, counts=np.full(3, n_e * det.gain_counts_per_e),
        extent_px=np.full(3, 27.0), level=float(det.bias_counts),
        threshold=sensor.detection.lit_pixel_counts,
    )  # fmt: skip
    pred = streak_errors(sensor, np.full(3, n_e), centres, streaks_px=np.tile(streak, (3, 1)))
    solver = np.trace(got.cov_px2, axis1=1, axis2=2)
    predicted = np.trace(pred.solver_cov_px2, axis1=1, axis2=2)
    # the clipped-streak term dominates (photon noise alone is 0.8 / sqrt(2e6) = 6e-4 px)
    assert np.all(solver > 100 * (0.8**2 / n_e))
    # the same term, the frame's from its measured streak and sum, the model's from the
    # expected ones: sigmas within 40 %. A clipped streak's lit pixels reach past its ends
    # (the solver measures 26.1 px for these 25), and the clipped-streak error over the phase
    # swings with the length by whole pixels (0.013 px at 26.1, 0.018 at 25); without the
    # term the prediction's sigma is 0.0006 px, 30x below the solver's
    np.testing.assert_allclose(np.sqrt(predicted), np.sqrt(solver), rtol=0.4)


def _rendered_cut(sensor, n_e, centre, streak, rng):
    """As :func:`_rendered`, on a frame whose column 0 is the stamp's column ``-c0``."""
    det = sensor.detector
    radius = CAPSULE_SIGMAS * det.psf_sigma_px + CAPSULE_PAD_PX
    cx, cy = centre
    stamp, sr, sc = streak_stamp_expected(
        sensor, x0=cx - 15.0, y0=cy, x1=cx + 15.0, y1=cy, electrons=n_e
    )
    cols = np.arange(sc, sc + stamp.shape[1])
    frames = np.broadcast_to(stamp[:, cols >= 0], (_K, stamp.shape[0], int(np.sum(cols >= 0))))
    counts = apply_noise(frames.copy(), sensor, rng=rng).astype(float) - det.bias_counts
    pad = 40  # the window sees no pixel left of the frame: zeros there
    planes = np.zeros((_K, counts.shape[1], counts.shape[2] + pad + 20))
    planes[:, :, pad : pad + counts.shape[2]] = counts
    # the solver cannot read left of column 0; zeros there are the same for a centroid
    gx, gy, _, _, _ = streak_centroids(
        planes,
        np.full(_K, cx + pad),
        np.full(_K, cy - sr),
        streaks=np.tile(streak * (1.0 + SYSTEMATIC), (_K, 1)),
        radius=radius,
    )
    return np.column_stack([gx - pad - cx, gy + sr - cy])


def test_short_streaks_keep_the_detector_centroid():
    sensor = _sensor()  # sigma 1.5 px, margin 2: re-centroided from 2 sigma + 4 = 7 px
    assert not is_streaked(sensor, 6.9) and is_streaked(sensor, 7.0)
    # below that length the solver weights the star by the detector's own noise model (the
    # CoG's sigma on its lit box): isotropic, and within the noise of the star at rest
    # (independent: photon noise alone, sigma_psf / sqrt(N), is its floor)
    n_e = 2.0e4
    got = streak_errors(sensor, [n_e], [[400.0, 300.0]], streaks_px=[[3.0, 0.0]], capsule=False)
    solver = got.solver_cov_px2[0]
    assert solver[0, 1] == 0.0 and solver[0, 0] == solver[1, 1]
    assert math.sqrt(solver[0, 0]) >= sensor.detector.psf_sigma_px / math.sqrt(n_e)


def test_anisotropic_propagation_reduces_to_the_isotropic_one():
    # C = e^2 (I - r r^T) is propagated_sigmas' error: both sandwiches agree to rounding
    rng = np.random.default_rng(0)
    v = rng.normal(size=(30, 3)) * [0.1, 0.1, 1.0]
    v /= np.linalg.norm(v, axis=1)[:, None]
    pairs = FieldStarsCam(np.repeat(np.arange(3), 10), np.arange(30), v, n_pointings=3)
    w, e = rng.uniform(1, 2, 30), rng.uniform(1, 3, 30)
    proj = np.eye(3) - v[:, :, None] * v[:, None, :]
    iso = propagated_sigmas(pairs, w, e)
    ani = propagated_covariance(pairs, w, e[:, None, None] ** 2 * proj)
    np.testing.assert_allclose(ani, iso, rtol=1e-12)


def test_along_streak_errors_move_the_attitude_along_them():
    # stars near the boresight whose errors lie along x alone: the attitude errs about y
    # (a shift of the field along x), not about x
    rng = np.random.default_rng(1)
    v = np.column_stack([rng.uniform(-0.05, 0.05, (40, 2)), np.ones(40)])
    v /= np.linalg.norm(v, axis=1)[:, None]
    pairs = FieldStarsCam(np.zeros(40, int), np.arange(40), v, n_pointings=1)
    cov = np.zeros((40, 3, 3))
    cov[:, 0, 0] = 1e-8
    proj = np.eye(3) - v[:, :, None] * v[:, None, :]
    cov = proj @ cov @ proj
    cross, _ = propagated_covariance(pairs, np.ones(40), cov)
    # the mean of 40 equal, independent x errors: 1e-4 / sqrt(40) on one axis, 0 on the other
    assert cross[0] == pytest.approx(math.sqrt(0.5 * 1e-8 / 40), rel=0.05)


def test_blends_of_neighbour_streaks_against_rendered_fields():
    # independent: drop Poisson neighbours (one class) around a streak, render the target and
    # the neighbours' streaks (parallel, as long) noiselessly, take the solver's capsule
    # centroid from the truth; the covariance of its shift against blend_cov_px2. The mean
    # square of a heavy-tailed shift: its tolerance is 4 of its own standard errors (from the
    # sample) plus 10 % for the model's capsule taken as a rectangle of the same area
    sensor = _sensor(psf_sigma_px=1.0)
    sigma = sensor.detector.psf_sigma_px
    radius = CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX
    rng = np.random.default_rng(7)
    n_e, f_nb, rho = 1.0e4, 3.0e3, 2.0e-3
    streak = np.array([20.0, 0.0])
    half = 40
    size = 2 * half + 1
    centre = float(half)

    def stamp(x, y, e):
        out = np.zeros((size, size))
        st, r0, c0 = streak_stamp_expected(
            sensor, x0=x - 10.0, y0=y, x1=x + 10.0, y1=y, electrons=e
        )
        a, b = max(r0, 0), min(r0 + st.shape[0], size)
        c, d = max(c0, 0), min(c0 + st.shape[1], size)
        if a < b and c < d:
            out[a:b, c:d] = st[a - r0 : b - r0, c - c0 : d - c0]
        return out

    target = stamp(centre, centre, n_e)
    planes = []
    for _ in range(1500):
        img = target.copy()
        n = rng.poisson(rho * size * size)
        for x, y in rng.uniform(-0.5, size - 0.5, (n, 2)):
            img += stamp(x, y, f_nb)
        planes.append(img)
    gx, gy, _, _, _ = streak_centroids(
        np.array(planes),
        np.full(len(planes), centre),
        np.full(len(planes), centre),
        streaks=np.tile(streak * (1.0 + SYSTEMATIC), (len(planes), 1)),
        radius=radius,
    )
    shift = np.column_stack([gx, gy]) - centre
    model = blend_cov_px2(n_e, streak, 1e9, sigma_px=sigma, neighbours=([f_nb], [rho]))
    for k in (0, 1):  # along and across the streak
        s2 = shift[:, k] ** 2
        tol = 4.0 * np.std(s2) / math.sqrt(len(s2)) + 0.10 * np.mean(s2)
        assert model[k, k] == pytest.approx(np.mean(s2), abs=tol)
    assert model[0, 0] > 2.0 * model[1, 1]  # a neighbour's light lies along the streak


def test_modelled_neighbours_leave_the_error_of_their_flux_ratio():
    # a neighbour the solver models from a flux off by a relative error e leaves the error of
    # its share of the light: d/d ln f of f / (N + f) = e N f / (N + f)^2, i.e. e N / (N + f)
    # of its pull (f the light it puts in the capsule, at most its own). One class, against
    # the same class unmodelled: a faint one leaves e^2 of the variance, one as bright as the
    # star between e^2 / 4 and e^2
    streak = np.array([20.0, 0.0])
    n_e, e = 1.0e4, 0.1
    for f_nb in (10.0, 1.0e4):
        whole = np.diag(
            blend_cov_px2(n_e, streak, 1e9, sigma_px=1.0, neighbours=([f_nb], [1e-3], [1.0]))
        )
        left = np.diag(
            blend_cov_px2(n_e, streak, 1e9, sigma_px=1.0, neighbours=([f_nb], [1e-3], [e]))
        )
        assert np.all(left <= e**2 * whole * (1 + 1e-9))
        assert np.all(left >= 0.25 * e**2 * whole * (1 - 1e-9))
        if f_nb < 100:  # f << N: N / (N + f) > 0.999
            np.testing.assert_allclose(left, e**2 * whole, rtol=2e-3)
    # the default: unmodelled
    default = blend_cov_px2(n_e, streak, 1e9, sigma_px=1.0, neighbours=([10.0], [1e-3]))
    np.testing.assert_array_equal(
        default, blend_cov_px2(n_e, streak, 1e9, sigma_px=1.0, neighbours=([10.0], [1e-3], [1]))
    )
