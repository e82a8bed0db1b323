"""The physical limit of star-sensor attitude accuracy (Fialho & Mortari 2019).

An ideal sensor of diameter D, exposing for t, limited only by diffraction and photon noise:

* per-star centroid Fisher information F_i = 12 zeta(5) pi^4 k^5 / (h^5 c^4) D^4 t C_i T_i^5
  (eq. 19), or eq. 17 integrated numerically over a passband x QE, or over a measured spectrum
  (:mod:`.centroid`);
* attitude Fisher matrix F = sum_i F_i (I - r_i r_i^T) (eq. 21), covariance P = F^-1 (eq. 20),
  theta_rms = sqrt(tr P) (eq. 22) = G D^-2 t^-1/2 (eqs. 23-24): one copy, in
  :mod:`starsense.attitude.covariance`; the result of one sensor in :mod:`.result`;
* the whole-sky and FOV-limited sensors (:mod:`.sky`), the N-brightest curve (:mod:`.brightest`)
  and the low-photon degradation (:mod:`.photons`).

Kernels are plain functions on NumPy arrays (no I/O), shared with the distributed path.
Stars are carried by :class:`~starsense.photometry.stars.BlackBodyStars`. Angles are radians.
"""

from starsense.analysis.limits.brightest import (
    BrightestCurve,
    brightest_checkpoints,
    brightest_curve,
    brightest_from_sums,
    brightest_order,
)
from starsense.analysis.limits.centroid import (
    FISHER_CONSTANT,
    centroid_fisher,
    centroid_fisher_numeric,
    centroid_fisher_spectrum,
    check_aperture,
)
from starsense.analysis.limits.photons import LowPhotonResult, low_photon_degradation
from starsense.analysis.limits.result import (
    LimitResult,
    boresight_frame,
    limit_from_fisher,
    limit_line,
)
from starsense.analysis.limits.sky import (
    fov_fishers,
    fov_limit,
    fov_results,
    in_cone,
    sky_fisher,
    sky_limit,
    star_weights,
)

# re-exported for the tests and users of the limit: the one copies live in earlier stages
from starsense.attitude.covariance import (
    covariance,
    fisher_components,
    fisher_from_components,
    fisher_matrix,
    theta_rms,
)
from starsense.photometry.stars import BlackBodyStars, b_v_from_spectral_type
from starsense.references.fialho2019 import G_INTERVAL as G_PAPER_INTERVAL
from starsense.references.fialho2019 import N_GALAXY

__all__ = [
    "FISHER_CONSTANT",
    "G_PAPER_INTERVAL",
    "N_GALAXY",
    "BlackBodyStars",
    "BrightestCurve",
    "LimitResult",
    "LowPhotonResult",
    "b_v_from_spectral_type",
    "boresight_frame",
    "brightest_checkpoints",
    "brightest_curve",
    "brightest_from_sums",
    "brightest_order",
    "centroid_fisher",
    "centroid_fisher_numeric",
    "centroid_fisher_spectrum",
    "check_aperture",
    "covariance",
    "fisher_components",
    "fisher_from_components",
    "fisher_matrix",
    "fov_fishers",
    "fov_limit",
    "fov_results",
    "in_cone",
    "limit_from_fisher",
    "limit_line",
    "low_photon_degradation",
    "sky_fisher",
    "sky_limit",
    "star_weights",
    "theta_rms",
]
