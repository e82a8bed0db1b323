"""Guide-star distribution for multi-area attitude determination (Lin et al. 2024).

A science camera whose square detector (field V x V) sits inside the lens's good-image circle
of diameter sqrt(2) V leaves four circular segments around the square; small detectors there
(the *attitude-determination areas*) give the attitude without disturbing the science frames.
Their total area is pi (sqrt(2) V / 2)^2 - V^2 = (pi/2 - 1) V^2 = 0.5708 V^2 (sec. 2.2: "0.57 V^2").

Focal-plane coordinates
    ``(x, y)`` in units of V, origin on the boresight, x and y along the camera's +x and +y
    axes (:mod:`starsense.geometry.attitude`). The science square is ``|x|, |y| <= 1/2``; the lens
    circle is ``x^2 + y^2 <= 1/2``. Area 1 is the segment beyond ``x = +1/2``, then
    counter-clockwise: 2 beyond ``y = +1/2``, 3 beyond ``x = -1/2``, 4 beyond ``y = -1/2``. A point
    maps to the camera-frame direction of the gnomonic projection with tangent-plane coordinates
    ``(x, y) * 2 tan(V/2)`` (so the square's edges subtend V through the boresight).

Configurations (Lin et al. 2024, sec. 4 and Table 1)
    ``one`` (area 1), ``two_adjacent`` (1, 2), ``two_symmetric`` (1, 3), ``three`` (1, 2, 3),
    ``four`` (1-4). By the four-fold symmetry each stands for every layout of its kind.

The paper's simulation (sec. 4), as implemented here
    * Candidate positions: the square lattice of step 7 % of V centred on the boresight
      (points ``0.07 (i, j) V``), kept where they fall inside an area. The paper says only
      "traversing the attitude determination areas with a step size of 7 % of the scientific
      camera's field of view"; a lattice centred on the boresight is invariant under 90 deg
      rotations, so all four areas get the same 25 candidates and the configurations differ only
      by layout.
    * Guide stars: five distinct lattice points, drawn uniformly among the combinations in which
      every area of the configuration holds at least one star (stars "distributed in" the areas;
      coverage is the paper's first characteristic). The paper enumerates "all possible
      combinations"; there are up to ~6e7 of them, so a uniform random sample of combinations
      estimates the same average probability.
    * Measurement error: each star's direction is displaced in its tangent plane by isotropic
      Gaussian noise of ``sigma`` rad per axis - the model behind eq. 3 (F = sum sigma^-2 (I - r
      r^T)).
    * Accuracy of a trial: the norm of the camera-frame error rotation vector,
      ``|delta phi|`` (:func:`starsense.geometry.attitude.small_rotation_angles`), whose mean
      square is tr P (eq. 4: "the variance of the overall attitude error"); ``metric="pointing"``
      uses the cross-boresight part ``|(delta phi_x, delta phi_y)|`` only.
    * Identification: the triangle algorithm runs in the loop
      (:func:`starsense.identify.batch.identify_triangles`):
      the catalogue is the trial's own guide stars (the paper's reference catalogue "does not
      include interfering stars"), the side tolerance is 3 standard deviations of a measured
      inter-star angle (``3 sqrt(2) sigma``), and a trial counts as a success only when the
      stars are identified correctly *and* the error is below the threshold. On the 7 % lattice
      some placements are ambiguous for every triangle (collinear and congruent star sets):
      0.14-0.16 % with four areas, 0.2-0.3 % with three, 0.7-0.9 % with one (two seeds of
      10,000), independent of sigma - the paper's Table 1 saturates at 99.87 % (four) and
      99.84 % (three).
    * sigma: a per-axis standard deviation by default. ``sigma_kind="3sigma"`` reads the
      paper's "measurement error" as a 3-sigma bound (standard deviation sigma / 3); with it the
      four-area column comes within 7 points of the paper's at every sigma, which no estimator
      can do under the per-axis reading (the Cramer-Rao bound caps the four-area cell at
      sigma = 0.3 arcsec near 24 %).

Analytic prediction: the attitude error is Gaussian with covariance P = F^-1 (eqs. 1-3), so
``P(|delta phi| < t)`` is a weighted chi-square probability; it is computed exactly as an
average over directions u of the chi (3 dof) or Rayleigh (2 dof) CDF of ``t / |L u|``
(``L L^T = P``), see :func:`probability_within`.

Units: angles are radians in every function and result (sigmas, thresholds, fields of view,
centres); results give arcsec and deg through properties for the edges (CLI, report, JSON). The
paper's published numbers are in :mod:`starsense.references.lin2024`.

Modules
    :mod:`~.focal_plane` (areas, lattice, placements), :mod:`~.metrics` (covariance, its
    probability, Monte Carlo solves), :mod:`~.table1` (Table 1), :mod:`~.selection` (choosing
    guide stars), :mod:`~.fields` (real fields, Tables 3-4).
"""

from starsense.analysis.guide_stars._common import METRICS, SIGMA_KINDS
from starsense.analysis.guide_stars.fields import (
    LAYOUT_COMBINATIONS,
    PAPER_FIELD_SIGMAS,
    FieldAccuracy,
    field_accuracy,
    field_stars,
    lin_layout,
)
from starsense.analysis.guide_stars.focal_plane import (
    AREA_OF_SEGMENT,
    CONFIGURATIONS,
    LENS_RADIUS,
    PAPER_STEP,
    SQUARE_HALF,
    area_index,
    attitude_area,
    configuration_areas,
    focal_to_vectors,
    in_configuration,
    lattice_points,
    sample_placements,
    triangle_fov_ratio,
)
from starsense.analysis.guide_stars.metrics import (
    batch_covariance,
    error_norm,
    monte_carlo_errors,
    probability_within,
)
from starsense.analysis.guide_stars.selection import (
    CRITERIA,
    SELECTION_SIGMA,
    GuideStarSelection,
    SelectionStatus,
    select_guide_stars,
)
from starsense.analysis.guide_stars.table1 import (
    ID_TOLERANCE_SIGMA,
    PAPER_FOV,
    PAPER_SIGMAS,
    PAPER_THRESHOLD,
    GuideStarTable,
    simulate_table1,
)
from starsense.identify.batch import ID_CORRECT, ID_FAILED, ID_WRONG, identify_triangles

__all__ = [
    "AREA_OF_SEGMENT",
    "CONFIGURATIONS",
    "CRITERIA",
    "ID_CORRECT",
    "ID_FAILED",
    "ID_TOLERANCE_SIGMA",
    "ID_WRONG",
    "LAYOUT_COMBINATIONS",
    "LENS_RADIUS",
    "METRICS",
    "PAPER_FIELD_SIGMAS",
    "PAPER_FOV",
    "PAPER_SIGMAS",
    "PAPER_STEP",
    "PAPER_THRESHOLD",
    "SELECTION_SIGMA",
    "SIGMA_KINDS",
    "SQUARE_HALF",
    "FieldAccuracy",
    "GuideStarSelection",
    "GuideStarTable",
    "SelectionStatus",
    "area_index",
    "attitude_area",
    "batch_covariance",
    "configuration_areas",
    "error_norm",
    "field_accuracy",
    "field_stars",
    "focal_to_vectors",
    "identify_triangles",
    "in_configuration",
    "lattice_points",
    "lin_layout",
    "monte_carlo_errors",
    "probability_within",
    "sample_placements",
    "select_guide_stars",
    "simulate_table1",
    "triangle_fov_ratio",
]
