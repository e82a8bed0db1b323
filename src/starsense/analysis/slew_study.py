"""How the ST-16 tolerable-slew curve moves with its two unstated parameters: PSF width and QE.

Dzamba & Enright 2014 give every parameter of their slew simulation (sec. 3.1) except the
static PSF width sigma_s (eq. 9: "it can be measured during calibration") and the detector's QE
curve (their Fig. 3, missing from our copy; the Reed model, eq. 8, uses its mean eta_Q). This
study sweeps both and compares the threshold magnitude m_t(w) at the paper's rates with the
thresholds its Table 2 implies (:data:`~starsense.references.dzamba2014.TABLE2_IMPLIED_MT`).

Method, as implemented:

* For each PSF width, one Monte Carlo (:func:`~starsense.analysis.slew.simulate_slew`, the same
  seed for every width) over a fine magnitude grid at rest and at the paper's rates, with the
  sensor's mean QE as the reference ``qe_ref``.
* m_t(w) at each rate is the faintest magnitude detected in at least ``criterion`` of the trials,
  refined by linear interpolation of the detection fraction between grid magnitudes (the same
  rule as the tolerable rate, read along magnitude instead of rate).
* The QE needs no further simulation: under the Reed and Liebe models (flat QE) the photo-
  electrons are proportional to eta_Q, and a star of magnitude m at eta_Q gives exactly the
  electrons, hence the same expected image and detections, as a star of magnitude
  m - 2.5 log10(eta_Q / qe_ref) at qe_ref. So m_t(eta_Q) = m_t(qe_ref) + 2.5 log10(eta_Q / qe_ref)
  at every rate: the QE shifts the whole curve by one offset, and only the PSF width changes its
  shape. For each width the best QE is the one whose offset centres the mismatches; what is left,
  half their spread, is the shape mismatch no QE can remove.

Checked once, outside the report (seed 0, sigma = 1-3 px, 20 trials): detecting with 4- instead
of 8-connected pixels, or counting a magnitude as detected at 10 % or 95 % of the trials instead
of half, leaves every width's shape mismatch at 0.10-0.17 mag, against 0.11-0.14 with the
defaults.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from starsense.analysis.inputs import root_seed
from starsense.analysis.slew import simulate_slew, tolerable_rate
from starsense.errors import InputError
from starsense.references.dzamba2014 import MAX_MAG, TABLE2_IMPLIED_MT
from starsense.units import DEG, to_edge

__all__ = [
    "DEFAULT_QE_MEANS",
    "DEFAULT_SIGMAS_PX",
    "MC_NOISE_MAG_20",
    "QE_SENSIBLE_RANGE",
    "SIGMA_SENSIBLE_RANGE_PX",
    "SlewStudy",
    "study_magnitudes",
    "study_slew",
]

#: PSF widths swept, px: from a nearly in-focus spot to a strong defocus
DEFAULT_SIGMAS_PX = (0.8, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0)
#: mean QEs swept over 400-800 nm (the shift is analytic, so this grid costs nothing)
DEFAULT_QE_MEANS = tuple(np.round(np.arange(0.25, 0.7001, 0.05), 2))
#: physically sensible mean QE over 400-800 nm for the MT9P031: at most its datasheet peak
#: (~55 % near 500 nm, falling to ~20 % at 800 nm; st16 preset), at least the 800 nm value
QE_SENSIBLE_RANGE = (0.20, 0.55)
#: physically sensible static PSF sigma, px: a defocused spot for sub-pixel centroiding is
#: 0.5-3 px (Liebe 2002); below ~0.5 px centroids lock to pixels, above ~3 px the star spreads
#: into the noise
SIGMA_SENSIBLE_RANGE_PX = (0.5, 3.0)

#: Monte Carlo standard deviation of one m_t with 20 trials per point on the 0.05 mag grid, mag:
#: the seed-to-seed standard deviation over seeds 0-4 at sigma = 1, 1.5 and 2.5 px is
#: 0.008-0.032 mag (tests/analysis/test_slew_study.py checks it); it scales as 1/sqrt(trials)
MC_NOISE_MAG_20 = 0.035


def study_magnitudes(step: float = 0.05, lo: float = 1.5, hi: float = 7.5) -> np.ndarray:
    """Return the magnitude grid of the study, `lo` to `hi` in `step` (mag)."""
    return np.round(np.arange(lo, hi + step / 2, step), 6)


@dataclass(frozen=True)
class SlewStudy:
    """m_t(w) over a (PSF sigma, mean QE) grid, against the paper's Table-2 thresholds.

    Attributes
    ----------
    sigmas_px : array (S,)
        PSF widths, px.
    qe_means : array (Q,)
        Mean QEs over the passband.
    qe_ref : float
        Mean QE of the simulation; other QEs shift the thresholds analytically.
    rates_rad_s : array (R,)
        Simulated rates, rad/s (rest first, then the paper's rates).
    magnitudes : array (M,)
        Simulated magnitudes at ``qe_ref``.
    detected_fraction : array (S, M, R)
        Detection fraction per width, magnitude and rate (as :class:`SlewResult`).
    threshold_ref : array (S, R)
        m_t at ``qe_ref``; NaN where not even the brightest magnitude is detected, or the
        faintest still is (the grid does not bracket it).
    paper_rates_rad_s : array (P,)
        The paper's rates (Table 2), rad/s; a subset of ``rates_rad_s``.
    paper_threshold : array (P,)
        The thresholds Table 2 implies at those rates (mean of the N_min = 2 and 3 values of
        :data:`~starsense.references.dzamba2014.TABLE2_IMPLIED_MT`), mag.
    model, sensor_name : str
    n_trials : int
    criterion : float
    seed : int or None
    """

    sigmas_px: np.ndarray
    qe_means: np.ndarray
    qe_ref: float
    rates_rad_s: np.ndarray
    magnitudes: np.ndarray
    detected_fraction: np.ndarray
    threshold_ref: np.ndarray
    paper_rates_rad_s: np.ndarray
    paper_threshold: np.ndarray
    model: str
    sensor_name: str
    n_trials: int
    criterion: float
    seed: int | None

    @property
    def _paper_columns(self) -> np.ndarray:
        return np.array(
            [int(np.argmin(np.abs(self.rates_rad_s - w))) for w in self.paper_rates_rad_s]
        )

    def thresholds(self, qe_means=None) -> np.ndarray:
        """Return m_t, shape (S, Q, R): the reference curve shifted by 2.5 log10(eta_Q / qe_ref)."""
        qe = self.qe_means if qe_means is None else np.atleast_1d(np.asarray(qe_means, float))
        shift = 2.5 * np.log10(qe / self.qe_ref)
        return self.threshold_ref[:, None, :] + shift[None, :, None]

    def mismatch(self) -> np.ndarray:
        """Return ours minus the paper's m_t at the paper's rates, shape (S, Q, P), mag."""
        return self.thresholds()[:, :, self._paper_columns] - self.paper_threshold

    def worst(self) -> np.ndarray:
        """Return the largest |mismatch| over the paper's rates, shape (S, Q), mag."""
        return np.abs(self.mismatch()).max(axis=2)

    def worst_at(self, i: int, qe_mean: float) -> float:
        """Return the largest |mismatch| over the paper's rates of width `i` at `qe_mean`, mag."""
        curve = self.threshold_ref[i] + 2.5 * np.log10(qe_mean / self.qe_ref)
        return float(np.abs(curve[self._paper_columns] - self.paper_threshold).max())

    def best_qe(self) -> tuple[np.ndarray, np.ndarray]:
        """Return, per width, the QE that minimises the worst mismatch and that minimum.

        The QE offset c minimising max_k |d_k + c| over the differences d_k = ours(qe_ref) -
        paper is minus the midrange of d, and the minimum is half the range of d.

        Returns
        -------
        qe : array (S,)
            Best mean QE (continuous, not restricted to the grid; NaN where m_t is undefined).
        worst : array (S,)
            The worst mismatch at that QE, mag: the shape mismatch no QE can remove.
        """
        d = self.threshold_ref[:, self._paper_columns] - self.paper_threshold
        mid = 0.5 * (d.max(axis=1) + d.min(axis=1))
        return self.qe_ref * 10.0 ** (-0.4 * mid), 0.5 * (d.max(axis=1) - d.min(axis=1))

    def tolerance_mag(self) -> np.ndarray:
        """Return the mismatch that still counts as agreement at each paper rate, shape (P,), mag.

        Two standard deviations of (ours - paper): our Monte Carlo noise
        (:data:`MC_NOISE_MAG_20` scaled to the trials) and half the disagreement of the N_min = 2
        and 3 thresholds Table 2 implies, in quadrature.
        """
        noise = MC_NOISE_MAG_20 * np.sqrt(20.0 / self.n_trials)
        half = np.array(
            [abs(a - b) / 2 for a, b in (TABLE2_IMPLIED_MT[w] for w in sorted(TABLE2_IMPLIED_MT))]
        )
        return 2.0 * np.hypot(noise, half)

    def best_pair(self, sensible: bool = True) -> dict:
        """Return the (sigma, QE) pair with the smallest worst mismatch, and its numbers.

        With ``sensible``, only widths in :data:`SIGMA_SENSIBLE_RANGE_PX` and QEs clipped to
        :data:`QE_SENSIBLE_RANGE` are considered (the QE offset then no longer centres the
        mismatches if it had to be clipped).
        """
        qe, _ = self.best_qe()
        lo, hi = QE_SENSIBLE_RANGE
        qe = np.clip(qe, lo, hi) if sensible else qe
        ok = np.isfinite(qe)
        if sensible:
            ok &= (self.sigmas_px >= SIGMA_SENSIBLE_RANGE_PX[0]) & (
                self.sigmas_px <= SIGMA_SENSIBLE_RANGE_PX[1]
            )
        if not ok.any():
            raise InputError("no PSF width of the study brackets m_t at every paper rate")
        curves = self.threshold_ref + 2.5 * np.log10(qe / self.qe_ref)[:, None]
        diff = curves[:, self._paper_columns] - self.paper_threshold
        worst = np.where(ok, np.abs(diff).max(axis=1), np.inf)
        i = int(np.argmin(worst))
        tol = self.tolerance_mag()
        paper_deg = to_edge(self.paper_rates_rad_s, DEG)
        return {
            "sigma_px": float(self.sigmas_px[i]),
            "qe_mean": float(qe[i]),
            "worst_mismatch_mag": float(worst[i]),
            "mismatch_mag": [float(v) for v in diff[i]],
            "threshold_mag": [float(v) for v in curves[i]],
            "static_threshold_mag": float(curves[i][0]) if np.isfinite(curves[i][0]) else None,
            "tolerance_mag": [float(v) for v in tol],
            "reproduces": bool(np.all(np.abs(diff[i]) <= tol)),
            "unmatched_rates_deg_s": [
                float(w) for w, d, t in zip(paper_deg, diff[i], tol, strict=True) if abs(d) > t
            ],
        }

    def to_dict(self) -> dict:
        """Return the study as JSON-ready values (deg/s at the edge; NaN as None)."""

        def clean(a):
            a = np.asarray(a, dtype=float)
            return [clean(x) for x in a] if a.ndim else (float(a) if np.isfinite(a) else None)

        qe, shape = self.best_qe()
        return {
            "sensor": self.sensor_name,
            "model": self.model,
            "sigmas_px": clean(self.sigmas_px),
            "qe_means": clean(self.qe_means),
            "qe_ref": self.qe_ref,
            "rates_deg_s": clean(to_edge(self.rates_rad_s, DEG)),
            "paper_rates_deg_s": clean(to_edge(self.paper_rates_rad_s, DEG)),
            "paper_threshold_mag": clean(self.paper_threshold),
            "threshold_mag": clean(self.thresholds()),
            "worst_mismatch_mag": clean(self.worst()),
            "best_qe_per_sigma": clean(qe),
            "shape_mismatch_mag": clean(shape),
            "best": self.best_pair(),
            "paper_static_threshold_mag": MAX_MAG,
            "n_trials": self.n_trials,
            "criterion": self.criterion,
            "seed": self.seed,
        }


def _with_psf(sensor, sigma_px: float):
    return sensor.with_(detector=dataclasses.replace(sensor.detector, psf_sigma_px=float(sigma_px)))


def study_slew(
    sensor,
    *,
    sigmas_px=DEFAULT_SIGMAS_PX,
    qe_means=DEFAULT_QE_MEANS,
    model: str = "reed",
    magnitudes=None,
    n_trials: int = 20,
    criterion: float = 0.5,
    rng: int | np.random.Generator | None = 0,
    progress=None,
) -> SlewStudy:
    """Sweep PSF sigma and mean QE; m_t at rest and at the paper's rates (Dzamba 2014 Table 2).

    Parameters
    ----------
    sensor : starsense.sensor.Sensor
        The star tracker (the ST-16 preset for the paper's comparison); its PSF width is replaced
        by each of `sigmas_px`, its mean QE is the reference QE.
    sigmas_px : array (S,)
        Static Gaussian PSF widths sigma_s (eq. 9), px, each > 0.
    qe_means : array (Q,)
        Mean QEs eta_Q over the passband (eq. 8), each in (0, 1].
    model : {"reed", "liebe"}
        Sensitivity model (the paper's Table 2 uses Reed, sec. 4).
    magnitudes : array (M,), optional
        Magnitude grid at the reference QE (default :func:`study_magnitudes`).
    n_trials : int
        Trials per (width, magnitude, rate).
    criterion : float
        Detection fraction that counts as detected.
    rng : None, int or numpy.random.Generator
        Root seed, the same for every width (common random numbers; a Generator gives one seed
        drawn from it; the result records it).
    progress : callable(int done, int total) or None
        Called after each width.

    Returns
    -------
    SlewStudy
    """
    if model not in ("reed", "liebe"):
        raise InputError(f"the slew study needs a flat-QE model, reed or liebe, got {model!r}")
    if sensor.detector.qe_curve:
        raise InputError(
            f"sensor {sensor.name!r} has a QE curve; the study sweeps a flat mean QE (qe_mean)"
        )
    sigmas = np.atleast_1d(np.asarray(sigmas_px, dtype=float))
    qes = np.atleast_1d(np.asarray(qe_means, dtype=float))
    if sigmas.size == 0 or not np.all(np.isfinite(sigmas) & (sigmas > 0)):
        raise InputError("sigmas_px must be a non-empty list of numbers > 0")
    if qes.size == 0 or not np.all(np.isfinite(qes) & (qes > 0) & (qes <= 1)):
        raise InputError("qe_means must be a non-empty list of numbers in (0, 1]")
    mags = study_magnitudes() if magnitudes is None else np.asarray(magnitudes, dtype=float)
    if mags.size < 2 or np.any(np.diff(mags) <= 0):
        raise InputError("magnitudes must be at least two strictly increasing numbers")
    paper_deg = np.array(sorted(TABLE2_IMPLIED_MT))
    paper_rates = paper_deg * DEG
    paper_mt = np.array([np.mean(TABLE2_IMPLIED_MT[w]) for w in paper_deg])
    rates = np.concatenate([[0.0], paper_rates])
    seed = root_seed(rng)
    fractions = []
    thresholds = np.full((len(sigmas), len(rates)), np.nan)
    for i, sigma in enumerate(sigmas):
        res = simulate_slew(
            _with_psf(sensor, sigma),
            model=model,
            magnitudes=mags,
            rates_rad_s=rates,
            n_trials=n_trials,
            criterion=criterion,
            rng=seed,
        )
        fractions.append(res.detected_fraction)
        for j in range(len(rates)):
            m_t, capped = tolerable_rate(res.detected_fraction[:, j], mags, criterion)
            if m_t is not None and not capped:
                thresholds[i, j] = m_t
        if progress is not None:
            progress(i + 1, len(sigmas))
    return SlewStudy(
        sigmas_px=sigmas,
        qe_means=qes,
        qe_ref=float(sensor.detector.mean_qe),
        rates_rad_s=rates,
        magnitudes=mags,
        detected_fraction=np.array(fractions),
        threshold_ref=thresholds,
        paper_rates_rad_s=paper_rates,
        paper_threshold=paper_mt,
        model=model,
        sensor_name=sensor.name,
        n_trials=int(n_trials),
        criterion=float(criterion),
        seed=seed,
    )
