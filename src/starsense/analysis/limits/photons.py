"""What a small sensor or short exposure loses to stars delivering few photons (sec. 3.3.2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense._validate import check_count
from starsense.analysis.limits.centroid import check_aperture
from starsense.attitude.covariance import (
    covariance,
    fisher_components,
    fisher_from_components,
    fisher_matrix,
    theta_rms,
)
from starsense.errors import SingularGeometryError
from starsense.photometry.blackbody import total_photons
from starsense.photometry.stars import BlackBodyStars

__all__ = ["MAX_PHOTON_TRIALS", "PHOTON_TRIAL_COST", "LowPhotonResult", "low_photon_degradation"]

#: most Monte Carlo draws of the low-photon degradation: each takes ~15 ms over the bundled
#: Hipparcos (``limit photons`` at 200 and 2,000 draws), so the cap bounds a run to ~25 minutes
#: (memory is bounded by the chunks of draws, ~0.2 GB)
MAX_PHOTON_TRIALS = 100_000
PHOTON_TRIAL_COST = "~15 ms per draw over the bundled Hipparcos"

#: stars expected to deliver more photons than this are drawn as deterministic
DETERMINISTIC_PHOTONS = 1e4


@dataclass(frozen=True)
class LowPhotonResult:
    """Sec. 3.3.2: what a small sensor or short exposure loses to stars delivering few photons.

    Attributes
    ----------
    expected_photons : array (N,)
        iota_i, the Poisson mean of photons from each star.
    n_below_one_photon : int
        Stars expected to deliver fewer than one photon.
    expected_observed_stars : float
        sum_i (1 - exp(-iota_i)): the mean number of stars with at least one photon.
    theta_ideal_rad : float
        The bound with every star's expected photons (eq. 22).
    theta_poisson_rad : float
        rms attitude bound over Monte Carlo draws of the photon counts N_i ~ Poisson(iota_i),
        F_i scaled by N_i / iota_i (information carried by the photons actually detected).
    degradation : float
        theta_poisson / theta_ideal (>= 1 in expectation: Jensen's inequality on tr F^-1).
    n_trials : int
        Monte Carlo draws.
    """

    expected_photons: np.ndarray
    n_below_one_photon: int
    expected_observed_stars: float
    theta_ideal_rad: float
    theta_poisson_rad: float
    degradation: float
    n_trials: int

    def to_dict(self) -> dict:
        """Return the JSON form (radians)."""
        return {
            "n_stars": len(self.expected_photons),
            "n_below_one_photon": self.n_below_one_photon,
            "expected_observed_stars": self.expected_observed_stars,
            "theta_ideal_rad": self.theta_ideal_rad,
            "theta_poisson_rad": self.theta_poisson_rad,
            "degradation": self.degradation,
            "n_trials": self.n_trials,
        }


def low_photon_degradation(
    stars: BlackBodyStars,
    *,
    diameter_m: float,
    exposure_s: float,
    n_trials: int = 200,
    rng: np.random.Generator | int | None = 0,
) -> LowPhotonResult:
    """Compute the low-photon degradation of the limit (Fialho & Mortari 2019, sec. 3.3.2).

    Stars whose expected photon count is large (> 1e4) are treated as deterministic: their
    relative Poisson fluctuation is below 1 %, and drawing them would only cost time.
    Trials with a singular geometry (too few stars seen) count as infinite error and make the
    result infinite: the sensor cannot solve in those exposures.

    Parameters
    ----------
    stars : BlackBodyStars
        The catalogue's stars.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).
    n_trials : int
        Monte Carlo draws of the photon counts, >= 1.
    rng : numpy Generator, int or None
        Random source or seed.

    Returns
    -------
    LowPhotonResult
    """
    check_aperture(diameter_m, exposure_s)
    n_trials = check_count(n_trials, "n_trials", MAX_PHOTON_TRIALS, PHOTON_TRIAL_COST)
    rng = np.random.default_rng(rng)
    iota = total_photons(
        stars.dilution, stars.temperature_k, diameter_m=diameter_m, exposure_s=exposure_s
    )
    w = stars.fisher_unit * diameter_m**4 * exposure_s
    r = stars.vectors
    ideal = theta_rms(covariance(fisher_matrix(r, w), len(stars)))
    fixed = iota > DETERMINISTIC_PHOTONS
    f_fixed = fisher_matrix(r[fixed], w[fixed])
    iv = iota[~fixed]
    # eq. 21's terms per photon of each drawn star: a draw's F adds counts @ comps
    comps = fisher_components(r[~fixed], w[~fixed] / iv)
    sq = []
    chunk = max(1, int(2e7 // max(len(iv), 1)))
    for start in range(0, n_trials, chunk):
        k = min(chunk, n_trials - start)
        counts = rng.poisson(iv, size=(k, len(iv))).astype(float)
        for f in f_fixed + fisher_from_components(counts @ comps):
            try:
                sq.append(np.trace(covariance(f)))
            except SingularGeometryError:
                sq.append(np.inf)
    poisson = float(np.sqrt(np.mean(sq)))
    return LowPhotonResult(
        expected_photons=iota,
        n_below_one_photon=int((iota < 1).sum()),
        expected_observed_stars=float(np.sum(-np.expm1(-iota))),
        theta_ideal_rad=ideal,
        theta_poisson_rad=poisson,
        degradation=poisson / ideal,
        n_trials=n_trials,
    )
