"""Close doubles: the photocentre replaces the matched star's direction."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense.sensor import load_sensor
from starsense.solve.blends import blend_radius_px, photocentres, track_mean
from starsense.solve.streaks import _streaks
from starsense.units import ARCSEC


def test_photocentre_of_equal_and_unequal_pairs():
    base = np.array([0.0, 0.0, 1.0])
    off = np.array([20 * ARCSEC, 0.0, 1.0])
    off /= np.linalg.norm(off)
    far = np.array([0.0, 1.0, 0.0])
    v = np.stack([base, off, far])
    tree = cKDTree(v)
    # equal pair: the midpoint (to first order in the 20 arcsec separation)
    out = photocentres(v, np.array([5.0, 5.0, 5.0]), tree, index=[0, 2], radius_rad=60 * ARCSEC)
    assert np.arctan2(out[0, 0], out[0, 2]) == pytest.approx(10 * ARCSEC, rel=1e-6)
    np.testing.assert_array_equal(out[1], far)  # no neighbour: unchanged
    # a companion 2.5 mag fainter carries 1/11 of the light: 20/11 arcsec towards it
    out = photocentres(v, np.array([5.0, 7.5, 5.0]), tree, index=[0], radius_rad=60 * ARCSEC)
    assert np.arctan2(out[0, 0], out[0, 2]) == pytest.approx(20 * ARCSEC / 11, rel=1e-3)
    # outside the radius: unchanged
    np.testing.assert_array_equal(
        photocentres(v, np.ones(3), tree, index=[0], radius_rad=10 * ARCSEC)[0], base
    )


def test_blend_radius_grows_with_the_psf():
    # two equal Gaussians are single-peaked below 2 sigma apart
    assert blend_radius_px(1.5) == pytest.approx(3.5)
    assert blend_radius_px(0.8) > 2 * 0.8


def _streak_scene(rng, shortest: float, longest: float):
    """The ST-16, a streak of random length and direction: sensor, PSF sigma, length, unit
    vectors along and across, and the capsule's radius."""
    from starsense.sensor import load_sensor
    from starsense.solve.streaks import CAPSULE_PAD_PX, CAPSULE_SIGMAS

    sensor = load_sensor("st16")
    sigma = sensor.detector.psf_sigma_px
    length, ang = rng.uniform(shortest, longest), rng.uniform(0.0, np.pi)
    u = np.array([np.cos(ang), np.sin(ang)])
    return (
        sensor,
        sigma,
        length,
        u,
        np.array([-u[1], u[0]]),
        CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX,
    )


@pytest.mark.parametrize("seed", range(40))
def test_a_neighbours_streak_in_the_capsule_moves_its_centroid_as_predicted(seed):
    """Two parallel streaks, the neighbour anywhere near the star's capsule: the solver's own
    capsule centroider (on a noiseless rendering) lands where the photocentre model says."""
    from scipy.spatial.transform import Rotation

    from starsense.detect.streak import SYSTEMATIC, streak_centroids
    from starsense.solve.blends import streak_photocentres

    rng = np.random.default_rng(seed)
    sensor, sigma, length, u, n, radius = _streak_scene(rng, 8.0, 30.0)
    # the neighbour: along anywhere over the streak, across within 1.5 capsule radii
    a, p = rng.uniform(-length, length), rng.uniform(-1.5, 1.5) * radius
    dmag = rng.uniform(0.0, 2.5)
    x0, y0 = 40.3, 40.7
    xy = np.array([[x0, y0], [x0 + a * u[0] + p * n[0], y0 + a * u[1] + p * n[1]]])
    yy, xx = np.mgrid[0:81, 0:81].astype(float)
    img = np.zeros((81, 81))
    for (cx, cy), flux in zip(xy, (1.0, 10 ** (-0.4 * dmag)), strict=True):
        for t in np.linspace(-0.5, 0.5, 200):
            px, py = cx + t * length * u[0], cy + t * length * u[1]
            img += flux / 200 * np.exp(-((xx - px) ** 2 + (yy - py) ** 2) / (2 * sigma**2))
    gx, gy = streak_centroids(
        img[None], np.array([x0]), np.array([y0]), streaks=(length * (1 + SYSTEMATIC) * u)[None],
        radius=radius,
    )[:2]  # fmt: skip
    measured = np.array([gx[0] - x0, gy[0] - y0])
    # the same scene on the sky: the sensor's boresight frame (identity attitude)
    centre = np.array([sensor.detector.columns / 2.0, sensor.detector.rows / 2.0])
    sky = xy - [x0, y0] + centre
    vectors = sensor.unproject(sky[:, 0], sky[:, 1])
    got = streak_photocentres(
        sensor, Rotation.identity(), vectors, mags=np.array([5.0, 5.0 + dmag]),
        tree=cKDTree(vectors),
        index=[0], streaks_px=(length * u)[None], radius_px=radius,
        length_px=np.array([length * (1 + SYSTEMATIC)]),
    ).vectors  # fmt: skip
    px, py = sensor.project(got)
    predicted = np.array([px[0], py[0]]) - centre
    # the model integrates a continuous Gaussian over the capsule, the centroider sums the pixels
    # whose centres are inside it: the capsule's edge is jagged by up to half a pixel, which
    # matters where only a neighbour's tail reaches in (its light there changes by ~e per
    # sigma): within 15 % of the shift the neighbour causes, plus 0.01 px
    assert np.hypot(*(predicted - measured)) < 0.15 * np.hypot(*measured) + 0.01, (
        predicted, measured, a, p, dmag,
    )  # fmt: skip


def _pixel_integrated_streak(shape, xy, flux, u, length, sigma):
    """A hand-made noiseless image: each source a uniform streak of Gaussians integrated over
    the pixels (erf differences), 400 steps along its length."""
    from scipy.special import ndtr

    rows, cols = shape
    img = np.zeros(shape)
    ex, ey = np.arange(cols + 1) - 0.5, np.arange(rows + 1) - 0.5
    for (cx, cy), f in zip(xy, flux, strict=True):
        for t in np.linspace(-0.5, 0.5, 400):
            px, py = cx + t * length * u[0], cy + t * length * u[1]
            gx = np.diff(ndtr((ex - px) / sigma))
            gy = np.diff(ndtr((ey - py) / sigma))
            img += f / 400 * np.outer(gy, gx)
    return img


@pytest.mark.parametrize("seed", range(24))
def test_the_capsule_reference_follows_the_centroider_from_where_it_started(seed):
    """Neighbours on either side, the centroider started away from the star (a detection on a
    piece of its streak): given where it started, the reference lands where the solver's own
    capsule centroider does on an independent noiseless rendering of the scene."""
    from scipy.spatial.transform import Rotation

    from starsense.detect.streak import SYSTEMATIC, streak_centroids
    from starsense.solve.blends import streak_photocentres

    rng = np.random.default_rng(100 + seed)
    sensor, sigma, length, u, n, radius = _streak_scene(rng, 15.0, 40.0)
    k = int(rng.integers(1, 4))  # neighbours, anywhere along, within 1.2 radii across
    a = rng.uniform(-1.2, 1.2, k) * length
    p = rng.uniform(-1.2, 1.2, k) * radius
    dmag = rng.uniform(0.0, 2.5, k)
    size = 161
    x0, y0 = 80.3, 80.6
    xy = np.array(
        [[x0, y0], *np.column_stack([x0 + a * u[0] + p * n[0], y0 + a * u[1] + p * n[1]])]
    )
    flux = np.concatenate([[1.0], 10 ** (-0.4 * dmag)])
    start = np.array([x0, y0]) + rng.uniform(-0.4, 0.4) * length * u  # on a piece of the streak
    seg = length * (1 + SYSTEMATIC) * u
    img = _pixel_integrated_streak((size, size), xy, flux, u, length, sigma)
    alone = _pixel_integrated_streak((size, size), xy[:1], flux[:1], u, length, sigma)
    got = streak_centroids(
        np.stack([img, alone]), np.full(2, start[0]), np.full(2, start[1]),
        streaks=np.stack([seg, seg]), radius=radius,
    )[:2]  # fmt: skip
    measured = np.array([got[0][0] - got[0][1], got[1][0] - got[1][1]])
    # the same scene on the sky, at the same pixel phase, the detection's start given
    det = sensor.detector
    centre = np.add(np.floor([det.columns / 2.0, det.rows / 2.0]), [0.3, 0.6])
    sky = xy - [x0, y0] + centre
    vectors = sensor.unproject(sky[:, 0], sky[:, 1])
    ref = streak_photocentres(
        sensor, Rotation.identity(), vectors, mags=5.0 + np.concatenate([[0.0], dmag]),
        tree=cKDTree(vectors), index=[0], streaks_px=(length * u)[None], radius_px=radius,
        length_px=np.array([length * (1 + SYSTEMATIC)]),
        starts_px=(start - [x0, y0] + centre)[None],
    ).vectors  # fmt: skip
    px, py = sensor.project(ref)
    predicted = np.array([px[0], py[0]]) - centre
    # the same centroider on two renderings of one scene, which differ by the pixel
    # quadrature only (400 steps here, the renderer's track): 2 % of the shift plus 0.01 px
    assert np.hypot(*(predicted - measured)) < 0.02 * np.hypot(*measured) + 0.01, (
        predicted, measured, a, p, dmag, start,
    )  # fmt: skip


@pytest.mark.parametrize("seed", range(16))
def test_the_capsule_reference_sees_the_frames_edge_and_its_clipping(seed):
    """A bright, saturated streak by the detector's edge, its neighbours' streaks running off
    it: the reference lands where the capsule centroider does on an independent rendering of
    the frame (pixels off the detector absent, every pixel clipped at the detector's clip)."""
    from scipy.spatial.transform import Rotation

    from starsense.detect.streak import SYSTEMATIC, streak_centroids
    from starsense.solve.blends import streak_photocentres

    rng = np.random.default_rng(300 + seed)
    sensor, sigma, length, u, n, radius = _streak_scene(rng, 30.0, 60.0)
    u = np.array([1.0, rng.uniform(-0.3, 0.3)])  # towards the right edge
    u /= np.hypot(*u)
    n = np.array([-u[1], u[0]])
    k = int(rng.integers(1, 4))  # neighbours, anywhere along, within 1.2 radii across
    a = rng.uniform(-1.2, 1.2, k) * length
    p = rng.uniform(-1.2, 1.2, k) * radius
    dmag = rng.uniform(0.0, 2.0, k)
    size = 161
    det = sensor.detector
    x0, y0 = size - 1 - 0.45 * length + rng.uniform(-3.0, 3.0), 80.6  # its end near the edge
    xy = np.array(
        [[x0, y0], *np.column_stack([x0 + a * u[0] + p * n[0], y0 + a * u[1] + p * n[1]])]
    )
    # the star's ridge 2-8 times what a pixel holds before it clips
    peak = 1.0 / (length * math.sqrt(2.0 * math.pi) * sigma)  # of one electron, per pixel
    electrons = rng.uniform(2.0, 8.0) * det.clip_e / peak
    flux = electrons * np.concatenate([[1.0], 10 ** (-0.4 * dmag)])
    start = np.array([x0, y0]) + rng.uniform(-0.3, 0.3) * length * u
    seg = length * (1 + SYSTEMATIC) * u
    # the frame: the window's right edge is the detector's (nothing beyond it), clipped
    img = _pixel_integrated_streak((size, size), xy, flux, u, length, sigma)
    alone = _pixel_integrated_streak((size, size), xy[:1], flux[:1], u, length, sigma)
    planes = np.minimum(np.stack([img, alone]), det.clip_e)
    got = streak_centroids(
        planes, np.full(2, start[0]), np.full(2, start[1]), streaks=np.stack([seg, seg]),
        radius=radius,
    )[:2]  # fmt: skip
    measured = np.array([got[0][0] - got[0][1], got[1][0] - got[1][1]])
    # the same scene on the detector: window column size - 1 is its last column
    corner = np.array([det.columns - size, math.floor(det.rows / 2.0) - 80.0])
    vectors = sensor.unproject(*(xy + corner).T)
    ref = streak_photocentres(
        sensor, Rotation.identity(), vectors, mags=5.0 + np.concatenate([[0.0], dmag]),
        tree=cKDTree(vectors), index=[0], streaks_px=(length * u)[None], radius_px=radius,
        length_px=np.array([length * (1 + SYSTEMATIC)]), starts_px=(start + corner)[None],
        zero_point_e=electrons / 10 ** (-0.4 * 5.0),
    ).vectors  # fmt: skip
    px, py = sensor.project(ref)
    predicted = np.array([px[0], py[0]]) - corner - [x0, y0]
    # as the test above (the same centroider on two renderings of one scene, which differ by
    # the pixel quadrature only): 2 % of the shift plus 0.01 px
    assert np.hypot(*(predicted - measured)) < 0.02 * np.hypot(*measured) + 0.01, (
        predicted, measured, a, p, dmag, start,
    )  # fmt: skip


def test_a_frames_zero_point_from_its_brightest_unclipped_streaks():
    from starsense.solve.blends import frame_zero_point_e

    mags = np.array([4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0])
    zero = 2.0e8
    electrons = zero * 10 ** (-0.4 * mags)
    clipped = mags < 5.5
    # a neighbour's light in one capsule (the third brightest unclipped) does not move it
    noisy = electrons * np.array([1, 1, 1, 1, 1.3, 1, 1, 1])
    assert frame_zero_point_e(noisy, clipped, mags) == pytest.approx(zero, rel=1e-12)
    # clipped streaks only: the largest lower bound
    low = electrons * np.array([0.5, 0.7, 0.6, 0.6, 0.6, 0.6, 0.6, 0.6])
    assert frame_zero_point_e(low, np.ones(8, bool), mags) == pytest.approx(0.7 * zero)
    # nothing measured
    assert frame_zero_point_e(np.zeros(3), None, mags[:3]) is None


def test_the_capsule_neighbours_come_from_the_whole_catalogue():
    """The solver's sky for the capsules holds every star of its catalogue with a magnitude in
    the band, not only the identification database's few per field."""
    from starsense.catalog import load_catalog
    from starsense.solve.identifiers import FieldIdentifiers

    cat = load_catalog("hipparcos")
    ids = FieldIdentifiers(cat, algorithm="hashing")
    vectors, mags, tree = ids.sky("V")
    finite = np.isfinite(np.asarray(cat.mags["V"], dtype=float))
    assert len(mags) == int(finite.sum()) and np.isfinite(mags).all()
    np.testing.assert_array_equal(vectors, np.asarray(cat.vectors)[finite])
    assert ids.sky("V")[2] is tree  # built once
    # the tree finds each star at its own place
    assert (tree.query(vectors[::997])[1] == np.arange(len(vectors))[::997]).all()


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_smeared_star_is_referenced_to_its_lights_time_average(sign):
    # a 5 deg field at 1 deg/s over 1 s: 650 px streaks whose images curve and change speed
    # along the track. The reference must be the time average of the star's image over the
    # exposure (the centre of its light), not its image at mid-exposure: the independent
    # average, 4,000 midpoint samples of the projection of the turning direction (error
    # < 1e-7 px), against the streaks the solver's rate gives (either sign)
    s = load_sensor("st16")
    sensor = s.with_(
        optics=dataclasses.replace(s.optics, focal_length_m=0.03 / math.radians(5.0)),
        exposure_s=1.0,
    )
    det = sensor.detector
    rng = np.random.default_rng(8)
    rot = Rotation.random(random_state=3)
    x, y = rng.uniform(0, det.columns, 40), rng.uniform(0, det.rows, 40)
    cam = sensor.unproject(x, y)
    rate = sign * math.radians(1.0) * np.array([0.6, 0.8, 0.1])
    streaks = _streaks(sensor, x, y, rate)
    assert np.hypot(*streaks.T).min() > 300
    out = track_mean(sensor, rot.inv().apply(cam), rotation=rot, streaks_px=streaks)
    t = (np.arange(4000) + 0.5) / 4000 - 0.5
    turned = Rotation.from_rotvec(-np.outer(t, rate) * sensor.exposure_s)
    mean = np.zeros((40, 2))
    for r in turned:
        mean += np.column_stack(sensor.project(r.apply(cam))) / len(t)
    got = np.column_stack(sensor.project(rot.apply(out)))
    # the effect is many times a bright star's capsule noise (0.001 px)
    assert np.abs(mean - np.column_stack([x, y])).max() > 0.01
    np.testing.assert_allclose(got, mean, atol=1e-5)


@pytest.mark.parametrize("seed", range(6))
def test_a_capsule_chasing_a_neighbours_light_grows_its_noise_as_its_gain_says(seed):
    """A collinear neighbour whose streak ends near the capsule's end: moved along, the window
    takes in or leaves its light, and each of the centroider's moves carries the noise on by
    the window's gain ``J``. Over 600 noisy renderings, the centroid's spread along the streak
    over the spread of one centre of gravity of the window held where the noiseless centroid
    lands (what the centroid's covariance describes) is ``noise_growth(J)``, ``J`` measured on
    the noiseless rendering, to the linear model's accuracy. The noise is that of a faint
    streak (the window's centre of gravity within 0.07 px): a move of less than 0.01 px
    stops the centroider, so a tenth of it would leave the spread to the stop rule."""
    from starsense.detect.streak import SYSTEMATIC, streak_centroids
    from starsense.solve.window_gain import noise_growth, window_gain

    rng = np.random.default_rng(seed)
    _, sigma, length, u, _, radius = _streak_scene(rng, 15.0, 30.0)
    seg = length * (1 + SYSTEMATIC) * u
    # the neighbour's near end 0-2 px past the star's capsule's segment end, 0.5-2 x as bright
    gap = 0.5 * (1 + SYSTEMATIC) * length + rng.uniform(0.0, 2.0)
    flux = rng.uniform(0.5, 2.0)
    size, x0, y0 = 121, 60.3, 60.7
    yy, xx = np.mgrid[0:size, 0:size].astype(float)

    def streak(cx, cy, f):
        t = np.linspace(-0.5, 0.5, 400)[:, None, None]
        px, py = cx + t * length * u[0], cy + t * length * u[1]
        return f * np.exp(-((xx - px) ** 2 + (yy - py) ** 2) / (2 * sigma**2)).mean(axis=0)

    at = gap + 0.5 * length
    both = streak(x0, y0, 1.0) + streak(x0 + at * u[0], y0 + at * u[1], flux)
    start = np.array([x0, y0])
    clean = streak_centroids(both[None], start[:1], start[1:], streaks=seg[None], radius=radius)
    c = np.array([clean[0][0], clean[1][0]])
    gain = window_gain(both, c, seg, radius=radius)
    noisy = both + rng.normal(0.0, 0.04 * both.max(), (600, size, size))
    gx, gy = streak_centroids(
        noisy, np.full(600, x0), np.full(600, y0), streaks=np.tile(seg, (600, 1)), radius=radius
    )[:2]
    # the window held at c: the pixels whose centres lie within the radius of its segment
    t = np.clip(((xx - c[0]) * seg[0] + (yy - c[1]) * seg[1]) / (seg @ seg), -0.5, 0.5)
    held = np.hypot(xx - c[0] - t * seg[0], yy - c[1] - t * seg[1]) <= radius
    w = np.where(held, noisy, 0.0)
    along = ((w * xx).sum(axis=(1, 2)) * u[0] + (w * yy).sum(axis=(1, 2)) * u[1]) / w.sum(
        axis=(1, 2)
    )
    ratio = np.std(gx * u[0] + gy * u[1]) / np.std(along)
    # the growth is the linear one at the noiseless fixed point; the gain changes over the
    # pixels the noisy fixed point wanders (0.4-0.85 within 2 px of it in one of these scenes)
    # and the 6 moves start up to 19 px away: within a factor of 2 (measured 0.7-1.75 here;
    # the spread of 600 draws is known to 3 %)
    assert 0.5 < ratio / float(noise_growth(gain)) < 2.0, (gain, ratio, gap, flux)


def test_a_streak_alone_has_no_window_gain():
    # the capsule (20 % longer than the streak, plus its radius) holds the whole streak one
    # pixel either way: its centre of gravity does not move
    from starsense.solve.window_gain import noise_growth, window_gain

    _, sigma, length, u, _, radius = _streak_scene(np.random.default_rng(3), 15.0, 30.0)
    yy, xx = np.mgrid[0:121, 0:121].astype(float)
    t = np.linspace(-0.5, 0.5, 400)[:, None, None]
    px, py = 60.3 + t * length * u[0], 60.7 + t * length * u[1]
    img = np.exp(-((xx - px) ** 2 + (yy - py) ** 2) / (2 * sigma**2)).mean(axis=0)
    gain = window_gain(img, np.array([60.3, 60.7]), 1.2 * length * u, radius=radius)
    assert abs(gain) < 1e-3
    assert float(noise_growth(gain)) == pytest.approx(1.0, abs=2e-3)
