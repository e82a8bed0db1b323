"""The datasheet's check: an end-to-end Monte Carlo scored against the prediction.

Random attitudes are rendered, detected, identified and solved
(:func:`starsense.analysis.montecarlo.run_montecarlo`); for every right solution the predicted
1-sigma of that very attitude comes from the same star model and catalogue as the datasheet
(:func:`starsense.analysis.datasheet.predict.nea_at`: the stars the tracker fits, through the
solver's own weights), the temporal noise, the measured pixel spatial error, the confusion of
unresolved neighbours and the sensor's rendered errors (PRNU, calibration residual) added in
quadrature (all vary from frame to frame at random attitudes). The
ratio measured rms / predicted rms is reported per axis, with its 95 % interval over the
frames (:func:`ratio_interval`: a ratio of 100 frames is known to ~10 %, of 36 to ~20 %).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import beta

from starsense.analysis.datasheet.model_noise import fit_holds_at_rate, model_nea_at_rate
from starsense.analysis.datasheet.predict import error_kinds, nea_at
from starsense.analysis.datasheet.sections import MonteCarloCheck
from starsense.analysis.montecarlo import montecarlo
from starsense.units import RAD_TO_ARCSEC, RAD_TO_DEG

__all__ = [
    "MEASURED_KEYS",
    "MIN_CHECKED_FRAMES",
    "no_frames_check",
    "ratio_interval",
    "run_checks",
    "score_montecarlo",
    "wrong_rate_upper",
]

#: right solutions needed to check the NEA: the rms of n frames is known to ~1 / sqrt(2 n)
#: (roll: one error per frame), 22 % at 10 frames, already the half-width of the 0.8-1.25
#: acceptance band (ln 1.25 = 0.22): with fewer, a right model cannot be told from a wrong one
MIN_CHECKED_FRAMES = 10
#: the fields of a Monte Carlo check measured on solved frames (None when none was measured)
MEASURED_KEYS = (
    "cross_rms_arcsec",
    "roll_rms_arcsec",
    "cross_predicted_arcsec",
    "roll_predicted_arcsec",
    "cross_ratio",
    "roll_ratio",
    "cross_ratio_robust",
    "roll_ratio_robust",
    "outliers_5sigma",
    "cross_ratio_ci95",
    "roll_ratio_ci95",
)

#: bootstrap resamples of the frames behind a ratio's 95 % interval (its ends to ~1 %)
N_BOOTSTRAP = 2000
#: the most frame draws held at once (resamples x frames): 32 MB of indices
_BOOTSTRAP_CHUNK = 1 << 22


def wrong_rate_upper(n_wrong: int, n_frames: int, confidence: float = 0.95) -> float:
    """Return the one-sided Clopper-Pearson upper bound on the wrong-identification rate."""
    if n_frames <= 0:
        return 1.0
    if n_wrong >= n_frames:
        return 1.0
    return float(beta.ppf(confidence, n_wrong + 1, n_frames - n_wrong))


def ratio_interval(measured_sq, predicted_sq, *, seed: int = 0) -> list[float] | None:
    """Return the 95 % interval of sqrt(mean(measured_sq) / mean(predicted_sq)) over the frames.

    The frames are resampled with replacement (:data:`N_BOOTSTRAP` times, pairs of measured
    and predicted kept together: the prediction differs from frame to frame) and the 2.5th and
    97.5th percentiles of the resampled ratios are returned (the percentile bootstrap). It
    says how far the ratio of this many frames could lie from the ratio of infinitely many:
    an error distribution with tails (a rare blend) widens it, as it should.

    Parameters
    ----------
    measured_sq : array_like, shape (N,)
        Each frame's squared error on the axis (cross: the mean of the two axes' squares).
    predicted_sq : array_like, shape (N,)
        Each frame's predicted variance on the axis (NaN where nothing was predicted).
    seed : int
        Seed of the resampling (the same frames give the same interval).

    Returns
    -------
    list of 2 float, or None
        Lower and upper ends; None with fewer than two frames.
    """
    a = np.asarray(measured_sq, dtype=float).ravel()
    p = np.asarray(predicted_sq, dtype=float).ravel()
    if len(a) < 2 or len(p) != len(a) or not np.isfinite(p).any():
        return None
    rng = np.random.default_rng(seed)
    chunk = max(1, _BOOTSTRAP_CHUNK // len(a))
    ratios = []
    for start in range(0, N_BOOTSTRAP, chunk):
        idx = rng.integers(0, len(a), size=(min(chunk, N_BOOTSTRAP - start), len(a)))
        pp = p[idx]
        seen = np.isfinite(pp)
        den = np.where(seen, pp, 0.0).sum(axis=1) / np.maximum(seen.sum(axis=1), 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios.append(np.sqrt(a[idx].mean(axis=1) / np.where(seen.any(axis=1), den, np.nan)))
    lo, hi = np.nanpercentile(np.concatenate(ratios), [2.5, 97.5])
    return [float(lo), float(hi)]


def _pct(values: np.ndarray, q: float) -> float | None:
    return float(np.percentile(values, q)) if len(values) else None


def score_montecarlo(res, model, *, fov, stars, predict: bool = True) -> dict[str, Any]:
    """Return the JSON-ready summary of a Monte Carlo run against the datasheet's prediction.

    Parameters
    ----------
    res : MonteCarloResult
        The run.
    model : StarModel
        The datasheet's star model.
    fov : RectangularFov
        The sensor's field.
    stars : FittedStars
        The stars the solver may fit, each counted when the fit holds it at the run's
        rate (:class:`starsense.analysis.datasheet.stars.FittedStars`); at a rate the
        prediction is the model fit's information of the smeared stars
        (:func:`starsense.analysis.datasheet.model_noise.model_nea_at_rate`). A centre-of-gravity
        solver is predicted at rest only (its windowed noise): at a rate its run is measured,
        not compared. At a rate, an attitude whose streaks' windows pass what the model fit
        may hold (:func:`~starsense.analysis.datasheet.model_noise.fit_holds_at_rate`) keeps
        its centroids' attitude: it is counted (``frames_beyond_fit``) and left out of the
        comparison.
    predict : bool
        Compare with the prediction (False: only the measurement is reported).

    Returns
    -------
    dict
        frames, solved, wrong, wrong_rate_upper95, measured and predicted rms per axis (arcsec)
        and their ratios (also from the median normalised error, and the count of frames off
        by more than 5 sigma), median and 95th-percentile solve time (ms), rate (deg/s). With
        fewer than ``MIN_CHECKED_FRAMES`` right solutions only the measured rms is reported.
    """
    right = len(res.errors_rad)
    if res.rate_rad_s > 0 and getattr(model, "refine", "cog") != "model":
        predict = False  # the centre-of-gravity solver is predicted at rest only
    out = {
        "frames": res.n_trials,
        "solved": res.n_solved - res.n_wrong,
        "wrong": res.n_wrong,
        "wrong_rate_upper95": wrong_rate_upper(res.n_wrong, res.n_trials),
        "rate_deg_s": res.rate_rad_s * RAD_TO_DEG,
        "median_ms": _pct(res.solve_ms, 50),
        "p95_ms": _pct(res.solve_ms, 95),
        "statuses": dict(res.statuses),
    }
    if right < MIN_CHECKED_FRAMES or not predict:  # measured, but too few frames to check
        return {**out, **_measured_only(res.errors_rad)}
    mats = Rotation.from_quat(res.truth_quat).as_matrix().reshape(-1, 3, 3)
    vectors, magnitudes, presence, catalogue = stars.at(res.rate_rad_s)
    e, held = res.errors_rad, np.ones(right, dtype=bool)
    if res.rate_rad_s > 0:
        cross, roll = model_nea_at_rate(
            model,
            fov,
            mats,
            rates_rad_s=res.rates_rad_s,
            vectors=vectors,
            magnitudes=magnitudes,
            presence=presence,
        )
        # an attitude whose streaks no fit holds keeps its centroids': the others are compared
        held = fit_holds_at_rate(
            model.sensor,
            fov,
            mats,
            rates_rad_s=res.rates_rad_s,
            vectors=vectors,
            magnitudes=magnitudes,
            n_stars=res.n_matched,
        )
        out["frames_beyond_fit"] = int(np.count_nonzero(~held))
        if np.count_nonzero(held) < MIN_CHECKED_FRAMES:
            return {**out, **_measured_only(e)}
        e, cross, roll = e[held], cross[held], roll[held]
    else:
        kinds = tuple(k for k in error_kinds(model.sensor) if k != "crb")
        kinds += ("catalogue",) if catalogue is not None else ()
        pred, _ = nea_at(
            model,
            fov,
            mats,
            vectors=vectors,
            magnitudes=magnitudes,
            kinds=kinds,
            catalogue=catalogue,
            presence=presence,
        )
        cross = np.sqrt(sum(pred[k][0] ** 2 for k in kinds))
        roll = np.sqrt(sum(pred[k][1] ** 2 for k in kinds))
    return {
        **out,
        **_ratios(e, cross, roll),
        "stars_matched_median": float(np.median(res.n_matched[held])),
    }


def _measured_only(e: np.ndarray) -> dict[str, Any]:
    """Return the measured rms per axis of right solutions' errors ``e`` (N, 3), rad; no ratio."""
    out = dict.fromkeys(MEASURED_KEYS)
    if len(e):
        out["cross_rms_arcsec"] = RAD_TO_ARCSEC * math.sqrt(
            float(np.mean(0.5 * (e[:, 0] ** 2 + e[:, 1] ** 2)))
        )
        out["roll_rms_arcsec"] = RAD_TO_ARCSEC * math.sqrt(float(np.mean(e[:, 2] ** 2)))
    return out


def _ratios(e: np.ndarray, cross: np.ndarray, roll: np.ndarray) -> dict[str, Any]:
    """Measured and predicted rms per axis, arcsec, their ratios, robust ratios, outliers."""
    meas_cross = math.sqrt(float(np.mean(0.5 * (e[:, 0] ** 2 + e[:, 1] ** 2))))
    meas_roll = math.sqrt(float(np.mean(e[:, 2] ** 2)))
    if not (np.isfinite(cross).any() and np.isfinite(roll).any()):  # no star predicted seen
        return {
            **dict.fromkeys(MEASURED_KEYS),
            "cross_rms_arcsec": meas_cross * RAD_TO_ARCSEC,
            "roll_rms_arcsec": meas_roll * RAD_TO_ARCSEC,
        }
    pc = math.sqrt(float(np.nanmean(cross**2)))
    pr = math.sqrt(float(np.nanmean(roll**2)))
    # robust ratios: the median normalised error against its Gaussian value (0.8326 for the
    # per-axis hypot / sqrt 2 of two axes, 0.6745 for one), insensitive to the odd blend
    z_cross = np.hypot(e[:, 0], e[:, 1]) / math.sqrt(2.0) / cross
    z_roll = np.abs(e[:, 2]) / roll
    median_cross = math.sqrt(2.0 * math.log(2.0)) / math.sqrt(2.0)
    return {
        "cross_rms_arcsec": meas_cross * RAD_TO_ARCSEC,
        "roll_rms_arcsec": meas_roll * RAD_TO_ARCSEC,
        "cross_predicted_arcsec": pc * RAD_TO_ARCSEC,
        "roll_predicted_arcsec": pr * RAD_TO_ARCSEC,
        "cross_ratio": meas_cross / pc,
        "roll_ratio": meas_roll / pr,
        "cross_ratio_robust": float(np.nanmedian(z_cross)) / median_cross,
        "roll_ratio_robust": float(np.nanmedian(z_roll)) / 0.6744897501960817,
        "outliers_5sigma": int(np.sum((z_cross > 5) | (z_roll > 5))),
        "cross_ratio_ci95": ratio_interval(0.5 * (e[:, 0] ** 2 + e[:, 1] ** 2), cross**2),
        "roll_ratio_ci95": ratio_interval(e[:, 2] ** 2, roll**2),
    }


def no_frames_check(rate_rad_s: float) -> MonteCarloCheck:
    """Return the check of a run of no frames: every measured number None.

    Parameters
    ----------
    rate_rad_s : float
        The rate the run would have had, rad/s.

    Returns
    -------
    MonteCarloCheck
    """
    return MonteCarloCheck(
        frames=0,
        solved=0,
        wrong=0,
        wrong_rate_upper95=1.0,
        rate_deg_s=rate_rad_s * RAD_TO_DEG,
        median_ms=None,
        p95_ms=None,
        statuses={},
        **dict.fromkeys(MEASURED_KEYS),
    )


def run_checks(sensor, cat, st, *, sky, client, tick, keep=None) -> dict[str, MonteCarloCheck]:
    """Return the Monte Carlo checks at rest and at the settings' rate, scored.

    ``sensor`` and ``cat`` are rendered and solved (:func:`starsense.analysis.montecarlo.
    montecarlo`) as ``st`` (DatasheetSettings) says; ``sky``: the star model, the field and
    the stars the solver may fit (:class:`~starsense.analysis.datasheet.stars.FittedStars`);
    ``client`` a Dask client or None; ``tick(name)`` is called after each run. ``keep``, a
    dict, receives each run's per-frame errors: rate (deg/s) -> the camera-frame X, Y, Z error
    (N, 3) of its right solutions, rad (:attr:`MonteCarloResult.errors_rad`).
    """
    model, fov, stars = sky
    runs = {}
    rate_trials = st.n_trials if st.n_rate_trials is None else st.n_rate_trials
    for key, rate, n in (
        ("monte_carlo", 0.0, st.n_trials),
        ("monte_carlo_at_rate", st.rate_rad_s, rate_trials),
    ):
        if n == 0:  # the prediction alone (starsense trade, the design page)
            runs[key] = no_frames_check(rate)
            continue
        res = montecarlo(
            sensor,
            cat,
            n_trials=n,
            rate_rad_s=rate,
            rng=st.seed,
            model=st.model,
            client=client,
            refine=st.refine,
        )
        runs[key] = MonteCarloCheck(**score_montecarlo(res, model, fov=fov, stars=stars))
        if keep is not None:
            keep[res.rate_deg_s] = res.errors_rad
        tick(key.replace("_", " "))
    return runs
