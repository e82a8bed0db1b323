"""The solver's last step: the attitude fitted to the identified stars' pixels (the forward model).

Once a frame is identified and a first attitude fitted to the centroids, the attitude (and the
body rate, when the frame is smeared) is refined by maximum likelihood on the pixels around the
identified stars (:func:`starsense.model.fit.fit_windows`): each star's flux and each window's
background are free, and the catalogue stars whose light reaches a window are in the model:

1. the detections' lit sums give the frame's zero point (electrons of a magnitude-0 star: the
   median over the brightest), or, without them, a first fit of the identified stars alone;
2. every catalogue star within reach of a window (its box, the PSF's extent and the streak) is
   predicted from its magnitude and that zero point; one too faint to matter (below a tenth of
   a pixel's noise over its PSF) is left out, the rest are drawn at their predicted flux (and
   move with the attitude);
3. the fit is made with them; where its fluxes move the zero point by more than
   :data:`ZERO_POINT_AGREES` (a lit sum misses a wide PSF's wings), the neighbours are
   predicted again and the fit repeated from its attitude.

Whether the fit's attitude replaces the centroids' one, and with what covariance, is
:mod:`starsense.solve.fit_judgement`'s to say.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from scipy.spatial import cKDTree

from starsense.errors import InputError
from starsense.model.fit import fit_windows
from starsense.model.psf import psf_of
from starsense.model.selection import fitted_min_electrons, psf_noise_e, streak_px
from starsense.model.windows import window_half_px
from starsense.solve.fit_judgement import MAX_REDUCED_CHI2, Refinement, judged
from starsense.solve.in_view import room_for, stars_in_view
from starsense.solve.streak_model import MIN_STREAK_SIGMAS

__all__ = [
    "refine_attitude",
    "refined_attitude",
]

#: two catalogue directions closer than this are one star, rad (0.2 arcsec)
SAME_STAR_RAD = 1e-6
#: a catalogue star closer than this to an identified one is part of its image (another
#: catalogue's copy of it, or a double the PSF does not split: the fitted flux holds both), px
MERGED_PX = 0.3
#: stars whose fluxes set the zero point
ZERO_POINT_STARS = 7
#: the neighbours are fitted again when the fit's zero point differs by more than this
#: (a lit sum misses a PSF's wings): a 5 % flux error of a neighbour at the noise's level is
#: below a tenth of its pull
ZERO_POINT_AGREES = 0.05
#: a neighbour below this fraction of a pixel's noise (over its PSF's area) is left out
NEGLIGIBLE_NOISE = 0.1
#: a fit at rest whose chi-square exceeds the pixels' count by this many of its standard
#: deviations (``sqrt(2 dof)``) is rejected: a frame whose streaks are short is fitted again with
#: the body rate free
REJECTED_SIGMAS = 3.0
#: the chi-square drop that keeps the rate: the likelihood-ratio test of 3 more parameters at a
#: false alarm of 1e-3 (``scipy.stats.chi2.isf(1e-3, 3)``)
RATE_EVIDENCE_CHI2 = 16.27


def _neighbours(
    sensor, plain, *, sky, place, rotation, reach_px: float, zero_point: float, noise_e: float
):
    """Return catalogue neighbours of the fitted stars: (apparent places, electrons)."""
    vectors, mags, tree = sky.vectors, sky.mags, sky.tree
    pixel_rad = 1.0 / sensor.focal_length_px
    lists = tree.query_ball_point(plain, 2.0 * math.sin(0.5 * reach_px * pixel_rad))
    owner = np.repeat(np.arange(len(plain)), [len(v) for v in lists])
    if owner.size == 0:
        return np.zeros((0, 3)), np.zeros(0)
    near = np.unique(np.concatenate([np.asarray(v, dtype=int) for v in lists]))
    # not a matched star itself (any of them): closer than MERGED_PX, its light is the star's
    # (the nearest by a tree: the stars of a deep wide field times their neighbours do not fit
    # in memory as a table of distances)
    d_min = cKDTree(plain).query(vectors[near], k=1)[0]
    keep = d_min > max(SAME_STAR_RAD, MERGED_PX * pixel_rad)
    near = near[keep]
    electrons = zero_point * 10.0 ** (-0.4 * mags[near])
    keep = electrons >= NEGLIGIBLE_NOISE * noise_e
    near, electrons = near[keep], electrons[keep]
    v = place(near)
    cam_z = v @ rotation.as_matrix()[2]
    front = cam_z > 0
    return v[front], electrons[front]


def _zero_point(fluxes, mags) -> float | None:
    """Electrons of a magnitude-0 star: the median over the brightest fitted stars."""
    ok = np.isfinite(fluxes) & (fluxes > 0) & np.isfinite(mags)
    if not ok.any():
        return None
    idx = np.flatnonzero(ok)
    top = idx[np.argsort(-fluxes[idx])[:ZERO_POINT_STARS]]
    return float(np.median(fluxes[top] / 10.0 ** (-0.4 * mags[top])))


def refine_attitude(
    image,
    sensor,
    rotation,
    *,
    ref,
    plain,
    mags,
    sky,
    cog_sigma_rad,
    rate_rad_s=None,
    electrons=None,
    fit_width=None,
    place=None,
    more=None,
    rate_hint_rad_s=None,
) -> Refinement:
    """Fit the attitude to the pixels of the identified stars (module docstring).

    Parameters
    ----------
    image : ndarray (rows, columns)
        The frame, counts.
    sensor : Sensor
    rotation : Rotation
        The centroid solution's attitude.
    ref, plain : ndarray (K, 3)
        The identified stars' reference directions (apparent places) and catalogue places.
    mags : ndarray (K,)
        Their catalogue magnitudes (in the band of ``sky``).
    sky : SkyStars
        Every catalogue star that may light a window.
    cog_sigma_rad : ndarray (3,)
        The centroid solution's 1-sigma per axis, rad.
    rate_rad_s : ndarray (3,), optional
        The body rate of a smeared frame (its streaks'), fitted from there; None: at rest.
    electrons : ndarray (K,), optional
        The stars' detected light (for the zero point of the neighbours' fluxes); without it
        a first fit of the identified stars alone measures them.
    fit_width : bool, optional
        Fit the PSF's width (default: the sensor's ``psf.fit_width``, and always for a
        Gaussian, whose width costs nothing to fit).
    rate_hint_rad_s : ndarray (3,), optional
        At rest (``rate_rad_s`` None): the rate a frame's short streaks suggest. Where the
        pixels reject the model at rest, the rate is fitted from there (:func:`_smeared_fit`).
    more : callable, optional
        ``more(zero_point_e, rotation, rate) -> (plain, reference, mags)``: the other stars in
        view (:func:`starsense.solve.in_view.stars_in_view`), fitted with the identified ones
        once the model describes those.

    Returns
    -------
    Refinement
    """
    fit_rate = rate_rad_s is not None
    rate = np.zeros(3) if rate_rad_s is None else np.asarray(rate_rad_s, float)
    if fit_width is None:
        fit_width = sensor.psf.fit_width or sensor.psf.is_gaussian
    mags = np.asarray(mags, float)
    if place is None:
        place = lambda rows: sky.vectors[np.asarray(rows, dtype=int)]  # noqa: E731
    opts = {"fit_rate": fit_rate, "fit_width": fit_width, "abort_chi2": 2.0 * MAX_REDUCED_CHI2}
    try:
        zp = None if electrons is None else _zero_point(np.asarray(electrons, float), mags)
        first = None
        if zp is None:  # the identified stars alone first: their fluxes give the zero point
            first = fit_windows(image, sensor, rotation, vectors=ref, rate_rad_s=rate, **opts)
            zp = _zero_point(first.fluxes_e, mags)
        if zp is None:  # no flux to draw the neighbours at: the identified stars alone
            if first is None:
                first = fit_windows(image, sensor, rotation, vectors=ref, rate_rad_s=rate, **opts)
            return judged(
                first, sensor, rotation, cog_sigma_rad=cog_sigma_rad, counts=(len(ref), 0)
            )
        neighboured = functools.partial(
            _with_neighbours,
            image=image,
            sensor=sensor,
            rotation=rotation,
            sky=sky,
            place=place,
            rate=rate,
            opts=opts,
        )
        stars = (plain, ref, mags)
        # the identified stars first: the model's verdict and the frame's smear are decided on
        # them (a real lens unlike the sensor's [psf] is refused before fainter stars are fitted)
        fit, counts = neighboured(stars=stars, first=first, zero_point=zp)
        also = ""
        if rate_hint_rad_s is not None and not fit_rate:  # at rest, unless the pixels say not
            moving = _smeared_fit(
                fit, neighboured.keywords, stars=stars, hint=rate_hint_rad_s, zero_point=zp
            )
            if moving is not None:
                (fit, counts), fit_rate = moving, True
                also = "; the stars' short streaks fitted with the body rate"
                smeared = dict(opts, fit_rate=True)
                neighboured = functools.partial(neighboured, rate=fit.rate_rad_s, opts=smeared)
        verdict = judged(
            fit, sensor, rotation, cog_sigma_rad=cog_sigma_rad, counts=counts, also=also
        )
        if more is None or not verdict.used:
            return verdict
        # the other stars in view, at the fit's zero point (its fluxes hold the PSF's wings, a
        # lit sum does not) and the rate fitted
        zp = _zero_point(fit.fluxes_e[: len(ref)], mags) or zp
        px, rx, mx = more(zp, fit.rotation, fit.rate_rad_s if fit_rate else None)
        if not len(mx):
            return verdict
    except (InputError, np.linalg.LinAlgError) as exc:
        return Refinement(None, False, f"model fit not used: {exc}")
    judge = functools.partial(judged, sensor=sensor, rotation=rotation, cog_sigma_rad=cog_sigma_rad)
    done, why = _in_view_fit(neighboured, judge, stars=(plain, ref, mags), more=(px, rx, mx),
                             first=fit, zero_point=zp, also=also)  # fmt: skip
    if done is not None:
        return done
    # the identified stars with their neighbours: the stars in view add information only
    return dataclasses.replace(
        verdict, note=f"{verdict.note}; the other stars in view left out: {why}"
    )


def _in_view_fit(neighboured, judge, *, stars, more, first, zero_point, also):
    """Fit the identified ``stars`` with the other stars in view ``more``, judged.

    The stars in view come brightest first; where their fit passes a fit's work (long streaks
    crossing a crowded field) the brightest half of them is fitted instead, again, at most
    :data:`MAX_HALVINGS` times. Returns the judged fit (None where none was used) and why not.
    """
    (plain, ref, mags), (px, rx, mx) = stars, more
    why = ""
    for n_added in _halvings(len(mx)):
        every = (
            np.vstack([plain, px[:n_added]]),
            np.vstack([ref, rx[:n_added]]),
            np.append(mags, mx[:n_added]),
        )
        try:
            fit, counts = neighboured(stars=every, first=first, zero_point=zero_point)
        except InputError as exc:  # past a fit's work
            why = str(exc)
            continue
        except np.linalg.LinAlgError as exc:
            return None, str(exc)
        if n_added < len(mx):
            also += f"; the {n_added} brightest of the {len(mx)} other stars in view ({why})"
        done = judge(fit, counts=counts, also=also)
        return (done, "") if done.used else (None, done.note)
    return None, why


#: the times the stars in view are halved (the brightest kept) when their fit passes its work
MAX_HALVINGS = 4


def _halvings(n: int) -> list[int]:
    """Return ``n`` and its successive halves (at most :data:`MAX_HALVINGS`), each >= 1."""
    out = [n]
    while len(out) <= MAX_HALVINGS and out[-1] > 1:
        out.append(out[-1] // 2)
    return out


def _smeared_fit(fit, keywords, *, stars, hint, zero_point):
    """Return the fit of ``stars`` with the body rate free (and its counts), or None.

    A frame whose streaks are too short to re-centroid is fitted at rest first. Where the
    pixels reject that model (its chi-square above the pixels' count by
    :data:`REJECTED_SIGMAS` of its own spread) the fit is made again with the rate free,
    started at ``hint`` (the rate the measured streaks suggest: the likelihood is even in the
    rate, flat at rest, so a fit started there stays) where it draws a streak of at least
    ``MIN_STREAK_SIGMAS`` PSF sigmas (shorter, the smear lengthens the image by under 15 %:
    a width fitted between the axes costs under 1 % of the stars' position information). It
    is kept where the likelihood ratio says so: the model at rest, fitted again on the same
    pixels (the streaks' windows) with the same neighbours, has a chi-square higher by more
    than :data:`RATE_EVIDENCE_CHI2` (3 rate parameters at a false alarm of 1e-3), and the
    rate fitted draws streaks as long as the hint had to (a tiny rate that takes up a
    model's small misfit of many bright stars is no smear).
    """
    excess = fit.chi2 - fit.dof
    if not math.isfinite(excess) or excess <= REJECTED_SIGMAS * math.sqrt(2.0 * fit.dof):
        return None
    image, sensor = keywords["image"], keywords["sensor"]
    shortest = MIN_STREAK_SIGMAS * psf_of(sensor).sigma_px
    if _longest_px(sensor, fit.rotation, stars[1], hint) < shortest:
        return None  # too short to matter: an image 15 % longer, < 1 % of the information lost
    opts = dict(keywords["opts"], fit_rate=True)
    last = {}
    try:
        moving = _with_neighbours(
            image,
            sensor,
            fit.rotation,
            stars=stars,
            first=None,
            zero_point=zero_point,
            sky=keywords["sky"],
            place=keywords["place"],
            rate=np.asarray(hint, float),
            opts=opts,
            last=last,
        )
        if not moving[0].converged:
            return None
        # the model at rest on the same pixels, with the same neighbours: the ratio's other side
        rest = fit_windows(
            image,
            sensor,
            last["start"],
            vectors=stars[1],
            rate_rad_s=np.zeros(3),
            fixed_vectors=last["neighbours"],
            fixed_electrons=last["electrons"],
            fluxes_e=last["fluxes"],
            window_rate_rad_s=last["rate"],
            **dict(keywords["opts"], fit_rate=False),
        )
    except (InputError, np.linalg.LinAlgError):
        return None
    if rest.n_pixels != moving[0].n_pixels or not rest.chi2 - moving[0].chi2 > RATE_EVIDENCE_CHI2:
        return None
    if _longest_px(sensor, moving[0].rotation, stars[1], moving[0].rate_rad_s) < shortest:
        return None  # the rate fitted draws streaks too short to matter: the frame is at rest
    return moving


def _longest_px(sensor, rotation, vectors, rate) -> float:
    """Return the longest streak body rate ``rate`` draws of stars ``vectors`` (ICRS), px."""
    cam = rotation.apply(vectors)  # the stars in the camera frame
    turn = np.linalg.norm(np.cross(np.asarray(rate, float), cam), axis=1)
    return float(np.max(turn, initial=0.0)) * sensor.exposure_s * sensor.focal_length_px


def _with_neighbours(
    image, sensor, rotation, *, stars, first, zero_point, sky, place, rate, opts, last=None
):
    """Fit ``stars`` (plain, reference, mags) with the catalogue neighbours reaching them.

    At the zero point ``zero_point`` (electrons of a magnitude-0 star), again if the fit's
    fluxes move it (a lit sum misses a PSF's wings). ``first``: a fit of the identified stars
    alone (its attitude, rate and fluxes the start), or None. ``last``, a dict, receives how
    the last fit started: ``start`` (attitude), ``rate``, ``neighbours`` and ``electrons``
    (the neighbours drawn) and ``fluxes`` (the stars' starting electrons).

    Returns
    -------
    ModelFit, (int, int)
        The fit, and the stars fitted and the neighbours drawn.
    """
    plain, ref, mags = stars
    fit, zp = first, zero_point
    n_fitted = 0 if fit is None else len(fit.fluxes_e)  # the first fit: no neighbours
    nv = np.zeros((0, 3))
    for _ in range(2):
        start = rotation if fit is None else fit.rotation
        nv, ne = _neighbours(
            sensor,
            plain,
            sky=sky,
            place=place,
            rotation=start,
            reach_px=_reach_px(sensor, rate),
            zero_point=zp,
            noise_e=psf_noise_e(sensor, rate),
        )
        if fit is first and fit is not None and not len(nv) and n_fitted == len(ref):
            break
        own = zp * 10.0 ** (-0.4 * mags)  # fitted fluxes where a fit has them
        if fit is not None:
            got = fit.fluxes_e[:n_fitted]
            own[:n_fitted] = np.where(np.isfinite(got) & (got > 0), got, own[:n_fitted])
        start_rate = rate if fit is None else fit.rate_rad_s
        if last is not None:
            last.update(start=start, rate=start_rate, neighbours=nv, electrons=ne, fluxes=own)
        fit = fit_windows(
            image,
            sensor,
            start,
            vectors=ref,
            rate_rad_s=start_rate,
            fixed_vectors=nv,
            fixed_electrons=ne,
            fluxes_e=own,
            **opts,
        )
        n_fitted = len(ref)
        new = _zero_point(fit.fluxes_e[: len(ref)], mags)
        if new is None or abs(new / zp - 1.0) < ZERO_POINT_AGREES or not len(nv):
            break
        zp = new
    return fit, (len(ref), len(nv))


def _reach_px(sensor, rate) -> float:
    """How far from a star a neighbour's light may reach its window, px."""
    psf = psf_of(sensor)
    streak = 0.0 if rate is None else streak_px(sensor, rate)
    return window_half_px(psf) * math.sqrt(2.0) + psf.radius_px + streak


def refined_attitude(
    image, att, sensor, *, db, ident, places, rate_rad_s, sky, place, points, rate_hint_rad_s=None
):
    """Return the solver's attitude refined on the pixels, and a note saying how.

    Parameters
    ----------
    image : ndarray
        The frame, counts.
    att : AttitudeSolution
        The attitude fitted to the centroids.
    sensor : Sensor
    db : identification database
        Its ``mags`` (in ``db.params.band``) give the matched stars' magnitudes.
    ident : identification result
        The matches (``catalog_index`` into ``db``).
    places : (ndarray, ndarray)
        The matched stars' catalogue and apparent places (K, 3).
    rate_rad_s : ndarray (3,) or None
        The body rate of a smeared frame (its streaks'), which starts the fit's; None at rest.
    rate_hint_rad_s : ndarray (3,), optional
        At rest: the rate short streaks suggest (:func:`refine_attitude`).
    sky : SkyStars
        The catalogue's stars in the band of ``db``.
    place : callable
        ``place(rows of sky) -> (M, 3)``: their apparent places
        (:func:`starsense.solve.references.sky_places`).
    points : CentroidPoints
        The detections (their lit sums set the neighbours' zero point).

    Returns
    -------
    AttitudeSolution, tuple of str
    """
    plain, ref = places
    index = np.asarray(ident.catalog_index)
    mags = np.asarray(db.mags, dtype=float)[index]
    electrons = None  # at rest the detections' lit sums (counts) give the zero point; a smeared
    if points.what == "detections" and rate_rad_s is None:  # frame's pieces do not: a first fit
        flux = np.asarray(points.flux, dtype=float)[np.asarray(ident.detection_index)]
        electrons = flux / sensor.detector.gain_counts_per_e
    # every catalogue star the model predicts above the noise joins the fit (in_view.py)
    room = room_for(sensor, len(ref), half_px=window_half_px(psf_of(sensor)), rate_rad_s=rate_rad_s)

    def more(zero_point_e, rotation, rate):
        return stars_in_view(
            sensor,
            rotation,
            plain=plain,
            sky=sky,
            place=place,
            min_electrons_e=fitted_min_electrons(sensor, 0.0 if rate is None else rate),
            zero_point_e=zero_point_e,
            max_stars=room,
        )

    opts = {"ref": ref, "plain": plain, "mags": mags, "sky": sky, "place": place}
    opts |= {"cog_sigma_rad": att.sigma_axes_rad, "rate_rad_s": rate_rad_s, "electrons": electrons}
    opts["rate_hint_rad_s"] = rate_hint_rad_s
    done = refine_attitude(image, sensor, att.rotation, more=more, **opts)
    if not done.used:
        return att, (done.note,)
    fit = done.fit
    return dataclasses.replace(
        att, rotation=fit.rotation, covariance_rad2=fit.covariance[:3, :3], method="model"
    ), (done.note,)
