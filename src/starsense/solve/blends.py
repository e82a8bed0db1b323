"""Close double stars: the direction a centroid of a blended pair really points to.

Two catalogue stars closer than the PSF can separate light one blob on the detector; its centre
of gravity is their flux-weighted photocentre, not either star. Matched to one of them, the
star's reference direction is then wrong by up to half the separation, many times its noise
(seen in rendered frames of the ESA camera: pairs 0.3-1.5 px apart gave 50-70 sigma errors).
Star trackers build their on-board catalogue with such pairs merged; here the matched star's
reference direction is replaced by the photocentre of the catalogue stars within the blend
radius.

On a smeared frame each star is centroided over a capsule around its whole streak
(:mod:`starsense.solve.streaks`), and a neighbour's streak that runs through that capsule adds
its light there, even when the two stars are well apart at rest: a neighbour of a third of the
star's flux 2.6 px away across a 13 px streak moved the centroid 0.4 px, 35 times the bright
star's noise. :func:`streak_photocentres` gives each such star the place its capsule centroider
lands: told where the centroider started (the solver's detections), that centroider itself on a
noiseless rendering of the star and of every catalogue star whose streak crosses its capsule,
less where it lands on the star alone (the same pixels, start and stop rule: a capsule can stay
on more than one place when a neighbour's streak runs through it); else the continuous fixed
point from the star, every catalogue star's streak (the same streak, shifted to the star's
place) clipped to the capsule, along the streak by its overlap and across it by the PSF's
Gaussian. The solver passes its whole catalogue as the neighbours (its identification database
keeps a few stars per field).

The noiseless rendering is the frame's: what runs off the detector is not there (a neighbour's
streak that leaves the frame pulls only with what it leaves on it), and, given the frame's
photometric zero point (:func:`frame_zero_point_e`, measured on its own matched streaks), every
pixel is clipped where the frame's clip (:attr:`~starsense.sensor.detector.Detector.clip_e`): a
saturated streak's ridge holds no more light than the ADC gives, so a neighbour's light across
it counts for less and its unclipped tails for more. Left out, the two put a bright star 1-3 px
off its light on 635 px streaks of an 8-bit camera, tens of times its noise.

Where a neighbour's streak reaches a capsule's end, the capsule chases its light and its
noise grows (:mod:`starsense.solve.window_gain`): the star's along-track sigma is grown by as
much (:func:`streak_reference`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.detect.streak import SYSTEMATIC, streak_centroids
from starsense.render.smear import streak_stamp_expected
from starsense.solve.streaks import CAPSULE_PAD_PX, CAPSULE_SIGMAS
from starsense.solve.window_gain import noise_growth, window_gain

__all__ = [
    "Photocentres",
    "blend_radius_px",
    "blended",
    "frame_zero_point_e",
    "photocentres",
    "streak_body_rate",
    "streak_photocentres",
    "streak_reference",
    "track_mean",
]

#: nodes of the average of a smeared star's image over the exposure (track_mean)
_TRACK_NODES = 4
#: a star's image moved by less than this is left where it is (a centroid's noise is 1e-3 px
#: at 1e6 electrons), px
_TRACK_FLOOR_PX = 1e-4
#: two catalogue directions closer than this are one star, rad (0.2 arcsec)
SAME_STAR_RAD = 1e-6
#: slices across a capsule its light is integrated over (Gauss-Legendre nodes)
_SLICES = 24
_GAUSS = np.polynomial.legendre.leggauss(_SLICES)


class Photocentres(NamedTuple):
    """Where matched stars' capsules land (:func:`streak_photocentres`)."""

    #: unit vectors (K, 3)
    vectors: np.ndarray
    #: each capsule's window gain at its centroid (K,), 0 alone
    #: (:func:`~starsense.solve.window_gain.window_gain`)
    gain: np.ndarray


def blend_radius_px(psf_sigma_px: float) -> float:
    """Return the separation below which two stars light one blob, px.

    Two equal Gaussians stay single-peaked below 2 sigma apart; half a pixel more covers the
    pixel grid. Above it the detector usually separates them (or the pair's residual is large
    enough for :func:`starsense.attitude.robust.robust_attitude` to drop it).
    """
    return 2.0 * float(psf_sigma_px) + 0.5


def photocentres(vectors, mags, tree, *, index, radius_rad: float) -> np.ndarray:
    """Return the reference directions of stars ``index``: photocentres with close neighbours.

    Parameters
    ----------
    vectors : ndarray (M, 3)
        Catalogue unit vectors (the identification database's stars).
    mags : ndarray (M,)
        Their magnitudes (the weights are 10^(-0.4 m)).
    tree : cKDTree
        On ``vectors``.
    index : ndarray (K,) of int
        The matched stars.
    radius_rad : float
        Blend radius, rad.

    Returns
    -------
    ndarray (K, 3)
        Unit vectors; a star with no neighbour keeps its own direction.
    """
    index = np.asarray(index, dtype=int)
    out = np.array(vectors[index], dtype=float)
    chord = 2.0 * math.sin(0.5 * float(radius_rad))
    for k, near in enumerate(tree.query_ball_point(out, chord)):
        if len(near) > 1:
            w = 10.0 ** (-0.4 * np.asarray(mags)[near])
            v = (w[:, None] * vectors[near]).sum(axis=0)
            out[k] = v / np.linalg.norm(v)
    return out


def blended(ref, plain, db, *, index, radius_rad: float) -> np.ndarray:
    """Return reference directions ``ref`` (K, 3) moved as ``plain``'s are to photocentres.

    ``ref``: the matched stars' references (apparent places of ``plain``, their database
    directions); each is moved by the offset of its photocentre with the database's
    neighbours within ``radius_rad`` (:func:`photocentres`) from ``plain``.
    """
    out = ref + photocentres(db.vectors, db.mags, db.tree, index=index, radius_rad=radius_rad)
    out = out - plain
    return out / np.linalg.norm(out, axis=1)[:, None]


def streak_photocentres(
    sensor,
    rotation,
    vectors,
    *,
    mags,
    tree,
    index,
    streaks_px,
    radius_px: float,
    length_px,
    starts_px=None,
    sky=None,
    zero_point_e=None,
) -> np.ndarray:
    """Return the reference directions of stars ``index`` centroided over their capsules.

    Parameters
    ----------
    sensor : Sensor
        The camera (projection and PSF sigma).
    rotation : Rotation
        The attitude, reference to camera (a first fit: the neighbours' offsets in pixels).
    vectors, mags, tree
        As :func:`photocentres`.
    index : ndarray (K,) of int
        The matched stars.
    streaks_px : ndarray (K, 2)
        Each matched star's streak, px (sign free).
    radius_px : float
        The capsule's radius around the streak, px.
    length_px : ndarray (K,)
        The length of the segment the capsule is drawn around, px (the streak lengthened by
        the centroider's allowance).
    starts_px : ndarray (K, 2), optional
        Where the centroider started each capsule (the detections' centroids), px: the
        centroider is then run on a noiseless rendering of the star and its neighbours
        (:func:`_pixel_shift`), from there, as on the frame. None: the continuous capsule's
        fixed point from the star (:func:`_capsule_centre`).
    sky : (vectors, mags, tree), optional
        The stars that may lie in a capsule (default ``vectors``, ``mags``, ``tree``: the
        matched stars' own catalogue); a star of it within :data:`SAME_STAR_RAD` of the
        matched star is that star.

    Returns
    -------
    Photocentres
        Unit vectors (K, 3), a star with no neighbour in its capsule keeping its own
        direction, and each capsule's window gain (0 without ``starts_px``).
    """
    index = np.asarray(index, dtype=int)
    out = np.array(vectors[index], dtype=float)
    gain = np.zeros(len(index))
    sigma = float(sensor.detector.psf_sigma_px)
    streaks = np.asarray(streaks_px, dtype=float).reshape(-1, 2)
    length = np.hypot(streaks[:, 0], streaks[:, 1])
    cam = rotation.apply(out)
    x0, y0 = sensor.project(cam)
    # reach: half the capsule's segment, its radius, and the PSF's tail beyond it, px -> rad
    reach = 0.5 * np.asarray(length_px, dtype=float) + radius_px + 3.0 * sigma
    mags = np.asarray(mags, dtype=float)
    sky_vectors, sky_mags, sky_tree = (vectors, mags, tree) if sky is None else sky
    for k, i in enumerate(index):
        # a neighbour's streak reaches the capsule from half a streak beyond it
        far = reach[k] + 0.5 * length[k]
        side = sensor.unproject(np.array([x0[k], x0[k] + far]), np.array([y0[k]] * 2))
        angle = math.acos(min(1.0, float(side[0] @ side[1])))
        near = np.asarray(sky_tree.query_ball_point(out[k], 2.0 * math.sin(0.5 * angle)), dtype=int)
        if sky is None:
            near = near[near != i]
        else:  # the matched star itself is in the sky too
            near = near[np.linalg.norm(sky_vectors[near] - out[k], axis=1) > SAME_STAR_RAD]
        if len(near) == 0 or length[k] == 0.0:
            continue
        u = streaks[k] / length[k]
        xn, yn = sensor.project(rotation.apply(sky_vectors[near]))
        along_n = (xn - x0[k]) * u[0] + (yn - y0[k]) * u[1]
        across_n = (xn - x0[k]) * -u[1] + (yn - y0[k]) * u[0]
        # only streaks that reach a capsule between where the centroider started and the star
        # (across: its radius and the PSF's tail; along: half the segment, the radius, half a
        # streak and the PSF's tail)
        moved = np.zeros(2) if starts_px is None else np.asarray(starts_px[k]) - [x0[k], y0[k]]
        path_along, path_across = abs(moved @ u), abs(moved @ [-u[1], u[0]])
        reach_along = 0.5 * (float(length_px[k]) + length[k]) + radius_px + 4.0 * sigma
        can = np.abs(across_n) <= radius_px + 4.0 * sigma + path_across
        can &= np.abs(along_n) <= reach_along + path_along
        if not can.any():
            continue
        near, xn, yn = near[can], xn[can], yn[can]
        along = np.concatenate([[0.0], along_n[can]])
        across = np.concatenate([[0.0], across_n[can]])
        flux = 10.0 ** (-0.4 * np.concatenate([[mags[i]], np.asarray(sky_mags)[near]]))
        if starts_px is not None:  # the centroider itself, from where it started
            got, gain[k] = _pixel_shift(
                sensor, np.column_stack([np.append(x0[k], xn), np.append(y0[k], yn)]), flux,
                streak=streaks[k] * float(length_px[k]) / length[k], start=starts_px[k],
                length=length[k], radius=radius_px, zero_point_e=zero_point_e,
            )  # fmt: skip
            shift = np.array([got @ u, got @ [-u[1], u[0]]])
        else:
            shift = _capsule_centre(
                along, across, flux, length[k], float(length_px[k]), radius_px, sigma
            )
            if shift is None:
                continue
        dx = shift[0] * u[0] - shift[1] * u[1]
        dy = shift[0] * u[1] + shift[1] * u[0]
        cam_k = sensor.unproject(np.array([x0[k] + dx]), np.array([y0[k] + dy]))[0]
        out[k] = rotation.inv().apply(cam_k)
    return Photocentres(out, gain)


def streak_reference(
    sensor, db, ref, *, index, rotation, streaks, pixel_rad, starts_px=None, sky=None,
    electrons=None, clipped=None,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Return ``ref`` with each smeared star's blend replaced by its capsule's photocentre.

    ``ref`` (K, 3) holds the matched stars' reference directions with their close doubles'
    photocentres (:func:`photocentres`, taken out here); ``streaks`` (K, 2) px are the
    streaks the stars were centroided over (:mod:`starsense.solve.streaks`, whose capsule
    this is), ``rotation`` a first fit and ``pixel_rad`` the pixel's angle; ``electrons``
    (K,) and ``clipped`` (K,) their capsules' sums and whether they clipped, which give the
    frame's zero point (:func:`frame_zero_point_e`; None: the rendering is not clipped).
    Every star is then moved to where its smeared light is centred (:func:`track_mean`).
    Returns the references (``ref`` itself when nothing moved) and the factor (K,) each
    star's along-track sigma grows by (:func:`~starsense.solve.window_gain.noise_growth` of
    its capsule's window gain).
    """
    sigma = sensor.detector.psf_sigma_px
    blended = photocentres(
        db.vectors, db.mags, db.tree, index=index, radius_rad=blend_radius_px(sigma) * pixel_rad
    )
    capsule, gain = streak_photocentres(
        sensor,
        rotation,
        db.vectors,
        mags=db.mags,
        tree=db.tree,
        index=index,
        streaks_px=streaks,
        radius_px=CAPSULE_SIGMAS * sigma + CAPSULE_PAD_PX,
        length_px=np.hypot(streaks[:, 0], streaks[:, 1]) * (1.0 + SYSTEMATIC),
        starts_px=starts_px,
        sky=sky,
        zero_point_e=None
        if electrons is None
        else frame_zero_point_e(electrons, clipped, np.asarray(db.mags)[index]),
    )
    moved = np.any(capsule != blended, axis=1)
    out = np.array(ref, dtype=float)
    if moved.any():  # a capsule holds a neighbour the blend did not
        new = ref[moved] - blended[moved] + capsule[moved]
        out[moved] = new / np.linalg.norm(new, axis=1)[:, None]
    grow = noise_growth(gain)
    mean = track_mean(sensor, out, rotation=rotation, streaks_px=streaks)
    if mean is out and not moved.any():  # nothing to refit
        return ref, grow
    return mean, grow


#: the brightest unclipped streaks a frame's zero point is the median of (the faint ones carry
#: more of the background's pedestal and noise)
_ZERO_POINT_STARS = 5


def frame_zero_point_e(electrons, clipped, mags) -> float | None:
    """Return the electrons of a magnitude-0 star in a frame, from its matched streaks.

    The median of ``electrons / 10^(-0.4 m)`` over the brightest unclipped streaks (a
    neighbour's light in one capsule does not move it); with every streak clipped, the largest
    of them (each clipped sum is a lower bound of the star's light).

    Parameters
    ----------
    electrons : array_like, shape (K,)
        Each matched star's capsule sum, electrons (0: none measured).
    clipped : array_like of bool, shape (K,), or None
        Whether each capsule clipped (None: none did).
    mags : array_like, shape (K,)
        The matched stars' catalogue magnitudes.

    Returns
    -------
    float or None
        Electrons; None when no streak was measured.
    """
    e = np.asarray(electrons, dtype=float)
    m = np.asarray(mags, dtype=float)
    clip = np.zeros(len(e), dtype=bool) if clipped is None else np.asarray(clipped, dtype=bool)
    ok = (e > 0) & np.isfinite(e) & np.isfinite(m)
    if not ok.any():
        return None
    ratio = e / 10.0 ** (-0.4 * m)
    free = np.flatnonzero(ok & ~clip)
    if len(free):
        top = free[np.argsort(-e[free], kind="stable")[:_ZERO_POINT_STARS]]
        return float(np.median(ratio[top]))
    return float(np.max(ratio[ok]))


def streak_body_rate(sensor, cam, streaks_px) -> np.ndarray:
    """Return the body rate (rad/s, camera frame) whose streaks fit ``streaks_px`` (N, 2).

    The streaks the solver centroided over come from one rate (:mod:`starsense.solve.
    streaks`), their signs consistent; to first order they are linear in it (``l_i = A_i w``,
    ``A_i`` the projection's), the least-squares ``w`` their rate (up to the sign every
    streak shares: :func:`track_mean` is even in it). ``cam`` (N, 3): the stars, camera frame.
    """
    n = len(cam)
    eps = 1e-6  # a turn of 1 microradian over the exposure
    turns = np.concatenate([[0.5 * eps * e, -0.5 * eps * e] for e in np.eye(3)])  # (6, 3)
    x, y = sensor.project(np.concatenate([Rotation.from_rotvec(t).apply(cam) for t in turns]))
    x, y = x.reshape(6, n), y.reshape(6, n)
    cols = [np.column_stack([x[2 * k + 1] - x[2 * k], y[2 * k + 1] - y[2 * k]]) for k in range(3)]
    a = np.column_stack([c.ravel() for c in cols]) / (eps / sensor.exposure_s)
    return np.linalg.lstsq(a, np.ravel(streaks_px), rcond=None)[0]


def track_mean(sensor, ref, *, rotation, streaks_px) -> np.ndarray:
    """Return ``ref`` (K, 3) moved to where each smeared star's light is centred, not mid-exposure.

    A star's direction turns on a circle about the rate axis during the exposure and its
    image runs along the projection of that circle, at a speed that varies along it: the
    centre of its light, the time average of its image, lies off its image at mid-exposure by
    the track's curvature and the change of speed, second order in the angle turned (0.01-0.05
    px at the corners of 300-650 px streaks at 1 deg/s: many times a bright star's noise,
    which the capsule centroid measures to 0.001 px). The average over the exposure
    (Gauss-Legendre, exact for a polynomial of degree 7 in time) at the rate the streaks give
    (:func:`streak_body_rate`), with the first fit's ``rotation`` (ICRS -> camera). Even in the
    rate: the streaks' common sign does not matter. ``ref`` itself where no star moves by
    :data:`_TRACK_FLOOR_PX` (below any centroid's noise).
    """
    ref = np.asarray(ref, dtype=float)
    cam = rotation.apply(ref)
    n = len(cam)
    rate = streak_body_rate(sensor, cam, streaks_px)
    nodes, weights = np.polynomial.legendre.leggauss(_TRACK_NODES)
    # s in (-1/2, 1/2) of the exposure, every node's turn of every star in one projection
    turned = [Rotation.from_rotvec(-rate * sensor.exposure_s * 0.5 * t).apply(cam) for t in nodes]
    xs, ys = sensor.project(np.concatenate([cam, *turned]))
    w = np.concatenate([[0.0], 0.5 * weights])[:, None]
    mx = np.sum(w * xs.reshape(-1, n), axis=0)
    my = np.sum(w * ys.reshape(-1, n), axis=0)
    if np.max(np.hypot(mx - xs[:n], my - ys[:n]), initial=0.0) < _TRACK_FLOOR_PX:
        return ref
    moved = sensor.unproject(mx, my)  # the light's centre, camera frame
    out = ref + rotation.inv().apply(moved - cam)
    return out / np.linalg.norm(out, axis=1)[:, None]


def _pixel_shift(
    sensor, xy, flux, *, streak, start, length: float, radius: float, zero_point_e=None
) -> np.ndarray:
    """Return how far the capsule centroider lands from where it lands on the star alone, px.

    Sources at ``xy`` (S, 2) px (the star first) draw parallel streaks of ``length`` px along
    ``streak`` (the capsule's segment, px); each is rendered noiselessly with the camera's PSF
    (:func:`starsense.render.smear.streak_stamp_expected`) into the window the solver reads
    around ``start`` (the detection it started from), the pixels off the detector emptied and,
    with ``zero_point_e`` (electrons of a magnitude-0 star; ``flux`` is ``10^(-0.4 m)``), each
    pixel clipped at the detector's :attr:`~starsense.sensor.detector.Detector.clip_e`; then
    :func:`starsense.detect.streak.streak_centroids` is run from there on the star with its
    neighbours and on the star alone: the same pixels, the same start, the same stop rule.
    Returns (dx, dy), px, and the window's gain where it landed with the neighbours
    (:func:`~starsense.solve.window_gain.window_gain`).
    """
    seg = np.asarray(streak, dtype=float)
    u = seg / math.hypot(*seg)
    half = math.ceil(math.hypot(*seg) + radius + 2.0)
    r0, c0 = math.floor(start[1]) - half, math.floor(start[0]) - half
    size = 2 * half + 1
    planes = np.zeros((2, size, size))
    for s, ((x, y), f) in enumerate(zip(xy, flux, strict=True)):
        dx, dy = 0.5 * length * u
        stamp, row0, col0 = streak_stamp_expected(
            sensor, x0=x - dx, y0=y - dy, x1=x + dx, y1=y + dy, electrons=float(f), pad_sigma=8.0
        )
        a, b = max(row0, r0), min(row0 + stamp.shape[0], r0 + size)
        c, d = max(col0, c0), min(col0 + stamp.shape[1], c0 + size)
        if b <= a or d <= c:
            continue
        piece = stamp[a - row0 : b - row0, c - col0 : d - col0]
        planes[0, a - r0 : b - r0, c - c0 : d - c0] += piece
        if s == 0:
            planes[1, a - r0 : b - r0, c - c0 : d - c0] += piece
    det, at = sensor.detector, np.arange(size)  # what lies off the detector is not in the frame
    planes[:, (r0 + at < 0) | (r0 + at >= det.rows), :] = 0.0
    planes[:, :, (c0 + at < 0) | (c0 + at >= det.columns)] = 0.0
    if zero_point_e is not None:  # in electrons, clipped where the frame clips
        planes = np.minimum(planes * zero_point_e, det.clip_e)
    gx, gy = streak_centroids(
        planes, np.full(2, start[0] - c0), np.full(2, start[1] - r0),
        streaks=np.stack([seg, seg]), radius=radius,
    )[:2]  # fmt: skip
    if not (np.isfinite(gx).all() and np.isfinite(gy).all()):
        return np.zeros(2), 0.0
    gain = window_gain(planes[0], np.array([gx[0], gy[0]]), seg, radius=radius)
    return np.array([gx[0] - gx[1], gy[0] - gy[1]]), gain


def _capsule_centre(along, across, flux, length, segment, radius, sigma):
    """Return where the capsule centroider stays (along, across the streak), px, or None.

    Sources at (``along``, ``across``) px from the star (the first), each a streak of
    ``length`` px; the capsule is within ``radius`` of a ``segment`` px long, centred on the
    centroid of the light it holds and moved there until it stays (the centroider's rule). The
    light is integrated across the capsule in slices (Gauss-Legendre): at ``t`` across, a
    source holds its Gaussian's density there times its streak's overlap with the capsule,
    whose round ends reach ``sqrt(radius^2 - t^2)`` past the segment.
    """
    nodes, weights = _GAUSS
    t = radius * nodes[None, :]  # (1, S) across, from the capsule's centre line
    dt = radius * weights[None, :]
    ends = 0.5 * segment + np.sqrt(np.maximum(radius**2 - t**2, 0.0))
    centre = np.zeros(2)
    for _ in range(50):
        rel_a, rel_p = (along - centre[0])[:, None], (across - centre[1])[:, None]
        dens = np.exp(-0.5 * ((t - rel_p) / sigma) ** 2) / (math.sqrt(2.0 * math.pi) * sigma)
        lo = np.maximum(rel_a - 0.5 * length, -ends)
        hi = np.minimum(rel_a + 0.5 * length, ends)
        w = flux[:, None] * dens * dt * np.maximum(hi - lo, 0.0) / length  # (sources, S)
        total = w.sum()
        if total <= 0.0:
            return None
        moved = centre + np.array([(w * 0.5 * (lo + hi)).sum(), (w * t).sum()]) / total
        if np.hypot(*(moved - centre)) < 1e-4:
            return moved
        centre = moved
    return centre
