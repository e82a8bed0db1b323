"""The forward model's expected pixels and their Jacobian; the fit on frames it did not draw."""

from __future__ import annotations

import math

import numpy as np
import pytest
from model_scene import model_image
from scipy.spatial.transform import Rotation

from starsense.geometry.attitude import small_rotation_angles
from starsense.model.fit import fit_windows
from starsense.model.psf import pixel_psf
from starsense.model.stamps import SEPARABLE_BOX_STAMPS, source_stamps, stamp_side
from starsense.model.tracks import NodePositions, node_positions, time_nodes
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
@pytest.mark.parametrize("rate_deg_s", [0.0, 1.0, 4.0])
@pytest.mark.slow
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
    frac, wts = time_nodes(30.0 * rate_deg_s, psf.sigma_px)
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
            # a source's light in another group than its own is given there (fixed)
            mus.append(np.einsum("gmhw,gm->ghw", e2.templates, _slots(windows, fluxes)) + e2.fixed)
        fd = (mus[0] - mus[1]) / (2 * (step[p]))
        assert np.abs(fd - jac[:, p]).max() < 1e-4 * np.abs(jac[:, p]).max()


@pytest.mark.parametrize("length", [60.0, 200.0])
@pytest.mark.parametrize("kind", ["gaussian", "moffat", "airy"])
def test_a_long_streak_is_each_nodes_light_within_the_reach(kind, length):
    """A 60 px (200 px) streak drawn is, pixel by pixel, the sum over its time nodes of the
    pixel-integrated PSF at each pixel centre within the reach (``half_px``) of the node: the
    same light a star at rest puts in its box. The reference is summed here node by node over
    the whole box, masked to each node's reach; agreement to round-off (1e-12 of the peak).
    A Gaussian's 60 px box (19 stamps) is summed as matrix products, its 200 px one (155
    stamps, past ``SEPARABLE_BOX_STAMPS``) node by node, as the other profiles are."""
    psf = pixel_psf(PSFSpec(kind=kind), 1.3)
    half = 5.0
    frac, wts = time_nodes(length, psf.sigma_px)
    x, y = 200.3 + 0.8 * length * frac, 300.7 + 0.6 * length * frac
    par = np.broadcast_to(np.eye(3), (1, len(frac), 3, 3))
    nodes = NodePositions(x[None], y[None], wts, par[..., 0, :], 2.0 * par[..., 1, :])
    box = (math.floor(y.min() - half + 0.5), math.floor(y.max() + half + 0.5) + 1,
           math.floor(x.min() - half + 0.5), math.floor(x.max() + half + 0.5) + 1)  # fmt: skip
    rows, cols = np.arange(box[0], box[1])[None], np.arange(box[2], box[3])[None]
    assert rows.size * cols.size > 10 * stamp_side(half) ** 2  # a box of many stamps
    by_nodes = rows.size * cols.size > SEPARABLE_BOX_STAMPS * stamp_side(half) ** 2
    assert by_nodes == (length > 100.0)  # both of a Gaussian's ways are drawn
    t, d = source_stamps(psf, nodes, np.array([0]), rows=rows, cols=cols, half_px=half)
    ref, ref_dx, ref_dy = np.zeros(t.shape[1:]), np.zeros(t.shape[1:]), np.zeros(t.shape[1:])
    r, c = rows[0][:, None], cols[0][None, :]
    for xk, yk, wk in zip(x, y, wts, strict=True):
        lo_r, lo_c = math.floor(yk - half + 0.5), math.floor(xk - half + 0.5)
        n = stamp_side(half)
        reach = (r >= lo_r) & (r < lo_r + n) & (c >= lo_c) & (c < lo_c + n)
        v, gx, gy = psf.evaluate(c - xk, r - yk)
        ref += wk * np.where(reach, v, 0.0)
        ref_dx -= wk * np.where(reach, gx, 0.0)  # d/dx of the star: -dP/d(dx), times dx/dp = 1
        ref_dy -= 2.0 * wk * np.where(reach, gy, 0.0)  # dy/dp = 2 for the second parameter
    np.testing.assert_allclose(t[0], ref, rtol=0, atol=1e-12 * ref.max())
    np.testing.assert_allclose(d[0, 0], ref_dx, rtol=0, atol=1e-12 * np.abs(ref_dx).max())
    np.testing.assert_allclose(d[0, 1], ref_dy, rtol=0, atol=1e-12 * np.abs(ref_dy).max())
    # nearly all the light of a Gaussian (99.9 %) lies within the reach of 5 px at sigma 1.3
    if kind == "gaussian":
        assert 0.999 < t.sum() <= 1.0


@pytest.mark.parametrize("kind", ["gaussian", "moffat"])
def test_a_box_cut_from_a_long_track_holds_the_light_of_the_whole_tracks(kind):
    """A 200 px streak's stamps on a box cut from its own (a group's box, the detector's edge:
    most nodes' reach lies off it) equal, pixel by pixel, that part of the whole box's (only
    the nodes reaching the cut are drawn). Round-off agreement (1e-12 of the peak)."""
    psf = pixel_psf(PSFSpec(kind=kind), 1.3)
    half, length = 5.0, 200.0
    frac, wts = time_nodes(length, psf.sigma_px)
    x, y = 200.3 + 0.8 * length * frac, 300.7 + 0.6 * length * frac
    par = np.broadcast_to(np.eye(3), (1, len(frac), 3, 3))
    nodes = NodePositions(x[None], y[None], wts, par[..., 0, :], 2.0 * par[..., 1, :])
    rows = np.arange(math.floor(y.min() - half), math.ceil(y.max() + half) + 1)[None]
    cols = np.arange(math.floor(x.min() - half), math.ceil(x.max() + half) + 1)[None]
    whole = source_stamps(psf, nodes, np.array([0]), rows=rows, cols=cols, half_px=half)
    r, c = slice(40, 75), slice(60, 110)  # across the track's middle
    cut = source_stamps(psf, nodes, np.array([0]), rows=rows[:, r], cols=cols[:, c], half_px=half)
    ref_t, ref_d = whole[0][:, r, c], whole[1][:, :, r, c]
    assert ref_t.max() > 0.0  # the cut holds part of the streak
    np.testing.assert_allclose(cut[0], ref_t, rtol=0, atol=1e-12 * ref_t.max())
    np.testing.assert_allclose(cut[1], ref_d, rtol=0, atol=1e-12 * np.abs(ref_d).max())


def _slots(windows, fluxes):
    out = np.zeros((windows.n_groups, windows.n_slots))
    out[windows.group, windows.slot] = fluxes
    return out


def test_fit_recovers_the_attitude_of_a_noiseless_frame():
    """A frame drawn by the model itself at a known attitude is fitted back to it (1e-4 px)."""
    sensor, v = _scene(n=15, seed=4)
    truth = Rotation.from_rotvec([2e-4, -1e-4, 5e-4])
    det = sensor.detector
    image, kept, fluxes = model_image(sensor, v, truth, (2e3, 2e4), background_e=50.0)
    counts = image * det.gain_counts_per_e + det.bias_counts
    start = Rotation.from_rotvec([0.0, 0.0, 3e-4]) * truth  # ~0.6 px off at the corners
    fit = fit_windows(counts, sensor, start, vectors=v[kept])
    err = small_rotation_angles(fit.rotation, truth) * sensor.focal_length_px
    assert fit.converged
    assert np.abs(err).max() < 1e-4
    np.testing.assert_allclose(fit.fluxes_e, fluxes, rtol=1e-6)


def test_the_chi_square_is_that_of_the_fit_where_it_stops():
    """A fit started from given fluxes reports the chi-square and information where it ends.

    The pixels are the model's with Gaussian noise of the model's variance, so at the fit the
    reduced chi-square is 1 within 5 of its sigma, sqrt(2 / dof); started from the right
    fluxes or from fluxes 40 % low (a lit sum missing a PSF's wings), the fit ends at the same
    optimum, and both report its chi-square (to 1e-3: a fit stops within a fraction of a sigma
    of it). A chi-square taken before the last step would carry the fluxes' misfit.
    """
    sensor, v = _scene(n=15, seed=5)
    det = sensor.detector
    truth = Rotation.from_rotvec([1e-4, 2e-4, -3e-4])
    # 80 e- of background: no pixel near zero
    image, kept, fluxes = model_image(sensor, v, truth, (3e3, 3e4), background_e=80.0)
    rng = np.random.default_rng(9)
    noisy = image + rng.standard_normal(image.shape) * np.sqrt(
        image + det.read_noise_e**2 + 1.0 / (12.0 * det.gain_counts_per_e**2)
    )
    counts = noisy * det.gain_counts_per_e + det.bias_counts  # float counts: no rounding
    right = fit_windows(counts, sensor, truth, vectors=v[kept], fluxes_e=fluxes)
    low = fit_windows(counts, sensor, truth, vectors=v[kept], fluxes_e=0.6 * fluxes)
    assert right.converged and low.converged
    assert abs(right.reduced_chi2 - 1.0) < 5.0 * math.sqrt(2.0 / right.dof)
    assert low.reduced_chi2 == pytest.approx(right.reduced_chi2, rel=1e-3)
    # the information at the fit's pixels: as a fit that first solved for the fluxes and the
    # backgrounds has it (its weights carry the 80 e- background; a Fisher weighted as at the
    # start, backgrounds at zero, would be ~5 times too large)
    first = fit_windows(counts, sensor, truth, vectors=v[kept])
    scale = np.sqrt(np.outer(np.diag(first.covariance), np.diag(first.covariance)))
    for fit in (right, low):  # each entry within 1 % of its axes' sigmas' product
        np.testing.assert_allclose(fit.covariance / scale, first.covariance / scale, atol=1e-2)


def test_a_rate_far_from_the_frames_is_refused_before_its_nodes_are_laid():
    """A fit started (or its windows laid) at a rate whose tracks run across the frame
    needs a node every PSF sigma or so of each, and windows as large: the fit refuses it with
    its work budget's error (nodes, or the windows' pixels) before allocating them, and stays
    small."""
    import resource

    from starsense.errors import InputError

    sensor, v = _scene(n=15, seed=4)
    truth = Rotation.from_rotvec([2e-4, -1e-4, 5e-4])
    det = sensor.detector
    image, kept, _ = model_image(sensor, v, truth, (2e3, 2e4), background_e=50.0)
    counts = image * det.gain_counts_per_e + det.bias_counts
    wild = np.radians([0.0, 0.0, 5000.0])  # 1,000 deg in a 0.2 s exposure: tracks circle
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    for opts in ({"rate_rad_s": wild, "fit_rate": True}, {"window_rate_rad_s": wild}):
        with pytest.raises(InputError, match="more than the"):
            fit_windows(counts, sensor, truth, vectors=v[kept], **opts)
    # ru_maxrss is in kB: the refusal allocates nothing near the nodes' gigabytes
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 500_000


def test_nodes_past_their_memory_are_refused_before_they_are_laid():
    """400 stars at a rate drawing 10,000 px tracks need 10^7 time nodes: under the fit's
    work in PSF evaluations, but their positions and derivatives alone would hold gigabytes
    (a wrong rate from blends measured as streaks took one process to 6 GB). The fit refuses
    them, counted before they are laid, and stays small."""
    import resource

    from starsense.errors import InputError

    sensor, v = _scene(n=400, seed=5)
    f, te = sensor.focal_length_px, sensor.exposure_s
    rate = np.array([2.0 * math.atan(1e4 / (2.0 * f)) / te, 0.0, 0.0])  # 10,000 px end to end
    image = np.zeros((sensor.detector.rows, sensor.detector.columns))
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises(InputError, match="nodes, more than"):
        fit_windows(image, sensor, Rotation.identity(), vectors=v, rate_rad_s=rate, fit_rate=True)
    # ru_maxrss is in kB: the refusal allocates nothing near the nodes' gigabytes
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 500_000


def test_track_nodes_refuses_more_nodes_than_allowed():
    """The tracks' quadrature counts its nodes before laying them: over the budget, an
    InputError; within it, the nodes of every source (time_nodes' count each)."""
    from starsense.errors import InputError
    from starsense.model.tracks import track_nodes

    sensor, v = _scene(n=15, seed=4)
    rate = np.radians([0.5, 0.3, 0.0])  # streaks of tens of pixels in 0.2 s
    frac, _, nodes = track_nodes(
        sensor, (v, v), Rotation.identity(), rate_rad_s=rate, sigma_px=0.8, moving=True
    )
    assert nodes.x.shape == (15, len(frac)) and len(frac) > 4
    with pytest.raises(InputError, match="nodes, more than"):
        track_nodes(
            sensor,
            (v, v),
            Rotation.identity(),
            rate_rad_s=rate,
            sigma_px=0.8,
            moving=True,
            max_nodes=15 * len(frac) - 1,
        )
    # an attitude that turns every star behind the camera (a diverged step): refused in words
    behind = Rotation.from_rotvec([np.pi, 0.0, 0.0])
    with pytest.raises(InputError, match="no fitted star projects"):
        track_nodes(sensor, (v, v), behind, rate_rad_s=rate, sigma_px=0.8, moving=True)


def _pair_at_rate(sensor, rate_rad_s, sep_px):
    """Node positions of two stars ``sep_px`` apart across a streak of 1 deg/s, and a third."""
    frac, wts = time_nodes(sensor.streak_length_px(float(np.linalg.norm(rate_rad_s))), 0.8)
    x0, y0 = 500.0, 380.0
    v = sensor.unproject(np.array([x0, x0 + sep_px, 300.0]), np.array([y0, y0, 200.0]))
    nodes = node_positions(
        sensor, v, Rotation.identity(), rate_rad_s=rate_rad_s, exposure_s=sensor.exposure_s,
        fractions=frac, weights=wts,
    )  # fmt: skip
    return v, nodes


def test_a_close_pair_at_a_rate_is_one_group_and_crossing_streaks_are_not():
    """Parallel tracks that share their pixels are one group; crossing streaks keep their own.

    At a body rate a close pair's two streaks lie along one line: fitted in two groups, each
    would own half of the other's pixels and hold the other's flux fixed at its last value.
    Two streaks crossing at right angles (a roll about a star between them) share only their
    crossing, and one group would need the square their union spans.
    """
    sensor = load_sensor("esa_blackfly")
    _, nodes = _pair_at_rate(sensor, np.radians([0.0, 1.0, 0.0]), 0.4)
    w, _ = make_windows(nodes.x, nodes.y, half_px=5.0, shape=(768, 1024),
                        free=np.ones(3, bool))  # fmt: skip
    assert w.group[0] == w.group[1] != w.group[2]
    streak = np.linspace(-15.0, 15.0, 9)
    x = np.vstack([500.0 + streak, np.full(9, 500.0)])  # one along the rows, one along the columns
    y = np.vstack([np.full(9, 380.0), 380.0 + streak])
    w, _ = make_windows(x, y, half_px=5.0, shape=(768, 1024), free=np.ones(2, bool))
    assert w.group[0] != w.group[1]


def test_a_close_pair_at_a_rate_fits_to_the_noise():
    """A close pair streaked by the body rate, drawn by the renderer with noise, fits to it.

    The renderer (:mod:`starsense.render`) draws the frame, not the model. At the fit the
    reduced chi-square is 1 within 5 of its sigma, sqrt(2 / dof): the pixels carry no light the
    model does not place (with the pair split over two groups the pair's pixels read 7-13).
    """
    from starsense.catalog.table import Catalog
    from starsense.render.scene import render_frame

    sensor = load_sensor("esa_blackfly")
    rate = np.radians([0.0, 1.0, 0.0])
    v, _ = _pair_at_rate(sensor, rate, 0.4)
    ra = np.degrees(np.arctan2(v[:, 1], v[:, 0]))
    dec = np.degrees(np.arcsin(v[:, 2]))
    cat = Catalog.from_columns(
        name="pair", source="test", epoch_yr=2016.0, ids=[1, 2, 3], ra_deg=ra, dec_deg=dec,
        mags={"V": [3.3, 3.5, 4.0]}, colours={"B-V": [0.6, 0.6, 0.6]},
    )  # fmt: skip
    frame = render_frame(sensor, Rotation.identity(), cat, rate_rad_s=rate, rng=11)
    fit = fit_windows(frame.image, sensor, Rotation.identity(), vectors=v, rate_rad_s=rate)
    assert fit.converged
    assert abs(fit.reduced_chi2 - 1.0) < 5.0 * math.sqrt(2.0 / fit.dof)
