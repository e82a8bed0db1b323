"""The statement checked on the Monte Carlo: the fraction of frames inside its bounds.

Per axis X, Y, Z and per rate, a frame is inside a bound when the absolute value of its error on
that axis (camera frame, :attr:`starsense.analysis.montecarlo.MonteCarloResult.errors_rad`: X
and Y across the boresight along the columns and rows, Z the roll, the axes of
:mod:`starsense.analysis.ecss.axes`) is at most the statement's total for that axis at that
rate (:attr:`~starsense.analysis.ecss.statement.Statement.totals`), at 1 sigma and at 3 sigma.
For a Gaussian error of the stated 1-sigma, 68.3 % and 99.7 % of the frames are inside.

A fraction counted on N frames scatters about the true one: 100 frames under a right 3-sigma
bound leave one or more outside one time in four. Each fraction is therefore judged too
(:func:`consistent_with`): consistent when the claim lies within the exact binomial
(Clopper-Pearson) 95 % interval of the count, two-sided for the 1-sigma bound (a claim of
68.3 %, too wide or too narrow), one-sided for the 3-sigma bound (a claim of at least 99.7 %).

The frames are the datasheet's check (rendered frames solved by the default solver, its right
solutions: :func:`starsense.analysis.datasheet.verify.run_checks`); a rate of the statement the
datasheet did not run is run here, the same frames per rate (:func:`frame_errors_at`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import betaincinv

from starsense.analysis.ecss.confidence import ONE_SIGMA, THREE_SIGMA
from starsense.analysis.ecss.statement import AXES, Statement
from starsense.analysis.montecarlo import montecarlo
from starsense.units import ARCSEC, DEG, RAD_TO_ARCSEC

__all__ = [
    "RATE_MATCH_DEG_S",
    "consistent_with",
    "coverage_rows",
    "frame_errors_arcsec",
    "frame_errors_at",
    "inside_fraction",
]

#: rates closer than this are one rate (deg/s): a statement's rate and a Monte Carlo's
RATE_MATCH_DEG_S = 1e-9


def inside_fraction(errors, bound) -> float | None:
    """Return the fraction of ``errors`` whose absolute value is at most ``bound``.

    Parameters
    ----------
    errors : array_like (N,)
        One axis's error of each frame (any unit, the bound's).
    bound : float or None
        The bound (None: not known).

    Returns
    -------
    float or None
        In [0, 1]; None without frames or without a bound.
    """
    e = np.asarray(errors, dtype=float).ravel()
    if bound is None or not math.isfinite(bound) or len(e) == 0:
        return None
    return float(np.count_nonzero(np.abs(e) <= bound)) / len(e)


def consistent_with(inside: int, n: int, claimed: float, *, two_sided: bool) -> bool | None:
    """Return whether ``inside`` of ``n`` frames is consistent with a coverage ``claimed``.

    The exact binomial (Clopper-Pearson) 95 % interval of the fraction: two-sided (the claim
    within ``[lo, hi]``) or one-sided (a claim of at least ``claimed``: consistent unless the
    95 % upper bound lies below it).

    Parameters
    ----------
    inside, n : int
        Frames inside the bound, and frames counted.
    claimed : float
        The fraction the bound claims, in (0, 1).
    two_sided : bool

    Returns
    -------
    bool or None
        None without frames.
    """
    if n <= 0:
        return None
    alpha = 0.05 / 2.0 if two_sided else 0.05
    hi = 1.0 if inside >= n else float(betaincinv(inside + 1, n - inside, 1.0 - alpha))
    if not two_sided:
        return bool(hi >= claimed)
    lo = 0.0 if inside <= 0 else float(betaincinv(inside, n - inside + 1, alpha))
    return bool(lo <= claimed <= hi)


def _judged(col: np.ndarray, bound, suffix: str, reason) -> dict:
    """Return the fractions inside a bound's 1- and 3-sigma values; whether chance explains each."""
    out = {}
    for tag, b, claimed in (("1sigma", bound[0], ONE_SIGMA), ("3sigma", bound[1], THREE_SIGMA)):
        frac = None if reason else inside_fraction(col, b)
        out[f"inside_{tag}{suffix}"] = frac
        out[f"consistent_{tag}{suffix}"] = (
            None
            if frac is None
            else consistent_with(
                round(frac * len(col)), len(col), claimed, two_sided=tag == "1sigma"
            )
        )
    return out


def _matching(frames: dict, rate_deg_s: float):
    for rate, errors in frames.items():
        if abs(rate - rate_deg_s) <= RATE_MATCH_DEG_S:
            return errors
    return None


def frame_errors_at(sensor, catalog, settings, *, rates_deg_s, have=None, client=None) -> dict:
    """Return the per-frame errors at each rate, running the rates ``have`` lacks.

    Parameters
    ----------
    sensor : Sensor
    catalog : Catalog
        The datasheet's catalogue (the frames show it and the solver database's stars).
    settings : DatasheetSettings
        The datasheet's: ``n_trials`` frames per rate, its seed, sensitivity model and solver.
    rates_deg_s : sequence of float
        The statement's rates, deg/s.
    have : dict, optional
        Per-frame errors already run (:attr:`starsense.analysis.datasheet.Datasheet.
        frame_errors_rad`): rate (deg/s) -> (N, 3) rad.
    client : dask.distributed.Client, optional

    Returns
    -------
    dict
        Rate (deg/s, as in ``rates_deg_s``) -> (errors (N, 3) rad of the right solutions,
        frames rendered, "datasheet" or "run for the statement").
    """
    have = have or {}
    out = {}
    for rate in rates_deg_s:
        errors = _matching(have, rate)
        if errors is not None:
            rendered = settings.n_trials
            if rate > 0 and settings.n_rate_trials is not None:
                rendered = settings.n_rate_trials
            out[rate] = (np.asarray(errors, dtype=float), rendered, "datasheet")
            continue
        if settings.n_trials == 0:
            out[rate] = (np.zeros((0, 3)), 0, "no frames (--trials 0)")
            continue
        res = montecarlo(
            sensor,
            catalog,
            n_trials=settings.n_trials,
            rate_rad_s=rate * DEG,
            rng=settings.seed,
            model=settings.model,
            client=client,
            refine=settings.refine,
        )
        out[rate] = (res.errors_rad, res.n_trials, "run for the statement")
    return out


def coverage_rows(statement: Statement, frames: dict) -> list[dict]:
    """Return, per rate and axis, the fraction of frames inside the 1- and 3-sigma totals.

    Parameters
    ----------
    statement : Statement
        Any confidence (restated at 1 and 3 sigma: :meth:`Statement.at_confidence`).
    frames : dict
        :func:`frame_errors_at`'s result, one entry per rate of the statement.

    Returns
    -------
    list of dict
        ``rate_deg_s``, ``axis`` (X, Y, Z), ``frames`` (right solutions counted),
        ``frames_rendered``,
        ``bound_1sigma_arcsec``, ``bound_3sigma_arcsec``, ``inside_1sigma``, ``inside_3sigma``
        (fractions in [0, 1]), ``consistent_1sigma``, ``consistent_3sigma`` (whether chance
        on this many frames explains the fraction: :func:`consistent_with`), the same against
        the sky ensemble's totals (the bound at a random attitude, what frames at random
        attitudes test: ``bound_1sigma_sky_ensemble_arcsec``, ``inside_1sigma_sky_ensemble``,
        ``consistent_1sigma_sky_ensemble``, ...), ``frames_from`` and ``reason`` (why a
        fraction is None).
    """
    one, three = statement.at_confidence(ONE_SIGMA), statement.at_confidence(THREE_SIGMA)
    rows = []
    for i, rate in enumerate(statement.rates_deg_s):
        errors, rendered, origin = frames[rate]
        for j, a in enumerate(AXES):
            b1 = one.totals[i][f"total_{a}_arcsec"]
            b3 = three.totals[i][f"total_{a}_arcsec"]
            e1 = one.totals[i].get(f"total_sky_ensemble_{a}_arcsec")
            e3 = three.totals[i].get(f"total_sky_ensemble_{a}_arcsec")
            col = errors[:, j] * RAD_TO_ARCSEC if len(errors) else np.zeros(0)
            reason = None
            if not len(errors):
                reason = f"no right solution at {rate:g} deg/s ({origin})"
            elif one.totals[i]["not_known"] and b1 == 0.0:
                reason = "every counted term is not known"
            rows.append(
                {
                    "rate_deg_s": rate,
                    "axis": a.upper(),
                    "frames": len(errors),
                    "frames_rendered": rendered,
                    "bound_1sigma_arcsec": b1,
                    "bound_3sigma_arcsec": b3,
                    **_judged(col, (b1, b3), "", reason),
                    "bound_1sigma_sky_ensemble_arcsec": e1,
                    "bound_3sigma_sky_ensemble_arcsec": e3,
                    **_judged(col, (e1, e3), "_sky_ensemble", reason),
                    "frames_from": origin,
                    "reason": reason,
                }
            )
    return rows


def frame_errors_arcsec(frames: dict) -> list[dict]:
    """Return the frames' errors as JSON: per rate ``rate_deg_s`` and ``errors_arcsec`` (N x 3)."""
    return [
        {"rate_deg_s": rate, "errors_arcsec": (errors / ARCSEC).tolist()}
        for rate, (errors, _, _) in frames.items()
    ]
