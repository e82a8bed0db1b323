"""The solver's last step: the attitude fitted to the identified stars' pixels (the forward model).

Once a frame is identified and a first attitude fitted to the centroids, the attitude (and the
body rate, when the frame is smeared) is refined by maximum likelihood on the pixels around the
identified stars (:func:`starsense.model.fit.fit_windows`): each star's flux and each window's
background are free, and the catalogue stars whose light reaches a window are in the model
(:mod:`starsense.solve.neighbours`); a frame fitted at rest whose short streaks suggest a smear
that matters is fitted again with the body rate free (:mod:`starsense.solve.smeared_fit`), the
likelihood ratio deciding, and a frame whose fit at
its streaks' rate is refused is fitted at rest (blends in a crowded field can measure as
streaks), kept where its pixels accept the model at rest; then the other stars in view join
(:mod:`starsense.solve.in_view`).

Whether the fit's attitude replaces the centroids' one, and with what covariance, is
:mod:`starsense.solve.fit_judgement`'s to say.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from starsense.errors import InputError
from starsense.model.fit import fit_windows
from starsense.model.psf import psf_of
from starsense.model.selection import fitted_min_electrons
from starsense.model.windows import window_half_px
from starsense.solve.fit_judgement import MAX_REDUCED_CHI2, Refinement, judged
from starsense.solve.in_view import room_for, stars_in_view
from starsense.solve.neighbours import fit_with_neighbours, frame_zero_point
from starsense.solve.smeared_fit import smeared_fit

__all__ = [
    "refine_attitude",
    "refined_attitude",
]


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
    misfit=None,
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
        At rest (``rate_rad_s`` None): the rate a frame's short streaks suggest. Where it draws
        streaks long enough to matter, the rate is fitted from there and kept where the
        likelihood ratio says so (:func:`starsense.solve.smeared_fit.smeared_fit`).
    misfit : callable, optional
        ``misfit(rotation=R)``: the median of the centroids' normalised residuals at an
        attitude (:func:`starsense.solve.fit_judgement.judged`'s move rule).
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
    at_rest = functools.partial(  # the same frame fitted at rest, the streaks' rate its hint
        refine_attitude, image, sensor, rotation, ref=ref, plain=plain, mags=mags, sky=sky,
        cog_sigma_rad=cog_sigma_rad, fit_width=fit_width, place=place, more=more,
        rate_hint_rad_s=rate, misfit=misfit,
    )  # fmt: skip
    judge = functools.partial(
        judged, sensor=sensor, rotation=rotation, cog_sigma_rad=cog_sigma_rad, misfit=misfit
    )
    if fit_width is None:
        fit_width = sensor.psf.fit_width or sensor.psf.is_gaussian
    mags = np.asarray(mags, float)
    if place is None:
        place = lambda rows: sky.vectors[np.asarray(rows, dtype=int)]  # noqa: E731
    opts = {"fit_rate": fit_rate, "fit_width": fit_width, "abort_chi2": 2.0 * MAX_REDUCED_CHI2}
    try:
        zp = None if electrons is None else frame_zero_point(np.asarray(electrons, float), mags)
        first = None
        if zp is None:  # the identified stars alone first: their fluxes give the zero point
            first = fit_windows(image, sensor, rotation, vectors=ref, rate_rad_s=rate, **opts)
            zp = frame_zero_point(first.fluxes_e, mags)
        if zp is None:  # no flux to draw the neighbours at: the identified stars alone
            if first is None:
                first = fit_windows(image, sensor, rotation, vectors=ref, rate_rad_s=rate, **opts)
            return judge(first, counts=(len(ref), 0))
        neighboured = functools.partial(
            fit_with_neighbours,
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
        verdict = judge(fit, counts=counts)
        if rate_hint_rad_s is not None and not fit_rate:  # at rest, unless the pixels say not
            moving = smeared_fit(
                fit, neighboured.keywords, stars=stars, hint=rate_hint_rad_s, zero_point=zp
            )
            fitted = "; the stars' short streaks fitted with the body rate"
            moved = None if moving is None else judge(moving[0], counts=moving[1], also=fitted)
            if moved is not None and (moved.used or not verdict.used):  # else at rest stands
                (fit, counts), fit_rate, verdict, also = moving, True, moved, fitted
                smeared = dict(opts, fit_rate=True)
                neighboured = functools.partial(neighboured, rate=fit.rate_rad_s, opts=smeared)
        if not verdict.used and rate_rad_s is not None:  # the streaks' rate: the pixels say no
            return _at_rest(verdict, at_rest)
        if more is None or not verdict.used:
            return verdict
        # the other stars in view, at the fit's zero point (its fluxes hold the PSF's wings, a
        # lit sum does not) and the rate fitted
        zp = frame_zero_point(fit.fluxes_e[: len(ref)], mags) or zp
        px, rx, mx = more(zp, fit.rotation, fit.rate_rad_s if fit_rate else None)
        if not len(mx):
            return verdict
    except (InputError, np.linalg.LinAlgError) as exc:
        refused = Refinement(None, False, f"model fit not used: {exc}")
        if rate_rad_s is not None and isinstance(exc, InputError):  # more than a fit holds
            return _at_rest(refused, at_rest)
        return refused
    done, why = _in_view_fit(neighboured, judge, stars=(plain, ref, mags), more=(px, rx, mx),
                             first=fit, zero_point=zp, also=also)  # fmt: skip
    if done is not None:
        return done
    # the identified stars with their neighbours: the stars in view add information only
    return dataclasses.replace(
        verdict, note=f"{verdict.note}; the other stars in view left out: {why}"
    )


def _at_rest(refused: Refinement, at_rest) -> Refinement:
    """Return the frame fitted at rest (``at_rest()``) where its streaks' rate was ``refused``.

    A crowded field's blended stars can measure as streaks: fitted at their rate, the frame's
    pixels reject the model, or the stars' and neighbours' tracks pass a fit's work. Fitted at
    rest, the rate its hint, the likelihood decides between the two models
    (:func:`starsense.solve.smeared_fit.smeared_fit`); a fit at rest the pixels accept (a
    reduced chi-square within :data:`~starsense.solve.fit_judgement.MAX_REDUCED_CHI2`) is
    used. Else the refusal stands: real streaks too long for a fit, fitted at rest, leave
    their pixels far from the model (windows at rest cut a stretch of each streak, whose place
    along it the windows' edges set, not the star), and the misfit, symmetric about the
    stars, need not pull the attitude that the judgement of a fit watches for.
    """
    done = at_rest()
    if not done.used or not done.fit.reduced_chi2 <= MAX_REDUCED_CHI2:
        return refused
    why = refused.note.removeprefix("model fit not used: ")
    return dataclasses.replace(
        done, note=f"{done.note}; fitted at rest (at the streaks' rate: {why})"
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


def refined_attitude(
    image,
    att,
    sensor,
    *,
    db,
    ident,
    places,
    rate_rad_s,
    sky,
    place,
    points,
    rate_hint_rad_s=None,
    misfit=None,
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
    misfit : callable, optional
        ``misfit(rotation=R)``: the median of the matched centroids' normalised residuals at
        an attitude (:func:`refine_attitude`).

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
    opts |= {"rate_hint_rad_s": rate_hint_rad_s, "misfit": misfit}
    done = refine_attitude(image, sensor, att.rotation, more=more, **opts)
    if not done.used:
        return att, (done.note,)
    fit = done.fit
    return dataclasses.replace(
        att, rotation=fit.rotation, covariance_rad2=fit.covariance[:3, :3], method="model"
    ), (done.note,)
