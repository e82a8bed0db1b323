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
    * Identification is assumed correct (the paper's reference catalogue "does not include
      interfering stars"); triangle identification in the loop is not simulated here.

Analytic prediction: the attitude error is Gaussian with covariance P = F^-1 (eqs. 1-3), so
``P(|delta phi| < t)`` is a weighted chi-square probability; it is computed exactly as an
average over directions u of the chi (3 dof) or Rayleigh (2 dof) CDF of ``t / |L u|``
(``L L^T = P``), see :func:`probability_within`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation
from scipy.special import erf

from starsense.errors import InputError
from starsense.geometry.sampling import fibonacci_sphere, random_attitudes

__all__ = [
    "ARCSEC_RAD",
    "AREA_OF_SEGMENT",
    "CONFIGURATIONS",
    "LENS_RADIUS",
    "PAPER_FOV_DEG",
    "PAPER_SIGMAS_ARCSEC",
    "PAPER_TABLE1_PERCENT",
    "GuideStarTable",
    "area_index",
    "attitude_area",
    "batch_covariance",
    "batch_svd_attitude",
    "configuration_areas",
    "error_norm",
    "focal_to_vectors",
    "in_configuration",
    "lattice_points",
    "monte_carlo_errors",
    "probability_within",
    "sample_placements",
    "simulate_table1",
    "triangle_fov_ratio",
]

ARCSEC_RAD = math.pi / (180.0 * 3600.0)
#: half side of the science square, units of V
SQUARE_HALF = 0.5
#: radius of the lens circle (diameter sqrt(2) V), units of V
LENS_RADIUS = math.sqrt(2.0) / 2.0
#: area of one circular segment outside the square: (pi/8 - 1/4) V^2 = 0.1427 V^2
AREA_OF_SEGMENT = math.pi / 8.0 - 0.25
#: the layouts of Lin et al. 2024, Table 1 (area numbers, counter-clockwise from +x)
CONFIGURATIONS: dict[str, tuple[int, ...]] = {
    "one": (1,),
    "two_adjacent": (1, 2),
    "two_symmetric": (1, 3),
    "three": (1, 2, 3),
    "four": (1, 2, 3, 4),
}
#: measurement errors of the paper's simulation (sec. 4, Table 1), arcsec
PAPER_SIGMAS_ARCSEC = (0.3, 0.25, 0.2, 0.1, 0.05, 0.02, 0.01)
#: Lin et al. 2024, Table 1: probability (%) of accuracy better than 0.1 arcsec, rows as
#: PAPER_SIGMAS_ARCSEC
PAPER_TABLE1_PERCENT: dict[str, tuple[float, ...]] = {
    "one": (0.15, 0.24, 0.44, 1.65, 9.92, 55.82, 73.45),
    "two_adjacent": (11.08, 16.46, 24.45, 54.67, 84.73, 98.60, 99.3),
    "two_symmetric": (7.48, 16.38, 46.10, 94.21, 95.85, 95.89, 95.89),
    "three": (9.04, 16.75, 39.18, 90.94, 99.18, 99.84, 99.84),
    "four": (84.90, 95.97, 98.99, 99.87, 99.87, 99.87, 99.87),
}
#: default V: the science field of the paper's observed star patterns 1 and 3 (sec. 5, Table 2):
#: 2048 px x 2 arcsec = 1.14 deg, the 1.6 deg pattern being the lens circle (1.6 / sqrt 2)
PAPER_FOV_DEG = 2048 * 2.0 / 3600.0
#: default lattice step, fraction of V (sec. 4)
PAPER_STEP = 0.07
METRICS = ("total", "pointing")


# ---------------------------------------------------------------------------------------------
# geometry


def configuration_areas(configuration: str) -> tuple[int, ...]:
    """Area numbers (1-4) of a named configuration; InputError for an unknown name."""
    try:
        return CONFIGURATIONS[configuration]
    except (KeyError, TypeError):
        raise InputError(
            f"configuration = {configuration!r} is not known; choose one of "
            f"{', '.join(CONFIGURATIONS)}"
        ) from None


def attitude_area(configuration: str = "four") -> float:
    """Total area of a configuration's attitude-determination areas, units of V^2.

    ``attitude_area("four")`` = pi/2 - 1 = 0.5708 (Lin et al. 2024, sec. 2.2: 0.57 V^2).
    """
    return len(configuration_areas(configuration)) * AREA_OF_SEGMENT


def _xy(xy: ArrayLike, name: str = "xy") -> NDArray[np.float64]:
    arr = np.asarray(xy, dtype=np.float64)
    if arr.ndim < 1 or arr.shape[-1] != 2:
        raise InputError(f"{name} must have shape (..., 2), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} has non-finite values")
    return arr


def area_index(xy: ArrayLike) -> NDArray[np.int_]:
    """Which attitude-determination area each focal-plane point is in.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Focal-plane points, units of V.

    Returns
    -------
    ndarray of int, shape (...)
        1-4 for the segments (1: x > 1/2, 2: y > 1/2, 3: x < -1/2, 4: y < -1/2), 0 inside
        the science square or outside the lens circle. Boundaries belong to the areas: the
        square's edges are excluded from the segments (strict), the lens circle included.
    """
    p = _xy(xy)
    x, y = p[..., 0], p[..., 1]
    in_lens = x * x + y * y <= LENS_RADIUS**2 * (1.0 + 1e-12)
    out = np.zeros(x.shape, dtype=int)
    out[in_lens & (x > SQUARE_HALF)] = 1
    out[in_lens & (y > SQUARE_HALF)] = 2
    out[in_lens & (x < -SQUARE_HALF)] = 3
    out[in_lens & (y < -SQUARE_HALF)] = 4
    return out


def in_configuration(xy: ArrayLike, configuration: str) -> NDArray[np.bool_]:
    """True where a point lies in one of the configuration's areas, shape (...)."""
    areas = configuration_areas(configuration)
    return np.isin(area_index(xy), areas)


def lattice_points(step: float = PAPER_STEP) -> tuple[NDArray[np.float64], NDArray[np.int_]]:
    """Candidate guide-star positions: the lattice ``step * (i, j)`` inside the four areas.

    Parameters
    ----------
    step : float
        Lattice step, fraction of V, in (0, 0.2].

    Returns
    -------
    xy : ndarray, shape (M, 2)
        Points, units of V.
    area : ndarray of int, shape (M,)
        Area number (1-4) of each point.
    """
    if not (np.isfinite(step) and 0.0 < step <= 0.2):
        raise InputError(f"step = {step!r} must be in (0, 0.2] (fraction of the field V)")
    n = math.ceil(LENS_RADIUS / step) + 1
    i = np.arange(-n, n + 1)
    gx, gy = np.meshgrid(i * step, i * step, indexing="ij")
    xy = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    area = area_index(xy)
    keep = area > 0
    return xy[keep], area[keep]


def _rng(rng) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def sample_placements(
    configuration: str,
    n_trials: int,
    n_stars: int = 5,
    step: float = PAPER_STEP,
    rng: np.random.Generator | int | None = None,
) -> NDArray[np.float64]:
    """Random guide-star placements on the lattice (Lin et al. 2024, sec. 4).

    Each placement is ``n_stars`` distinct lattice points of the configuration's areas, drawn
    uniformly among the combinations that put at least one star in every area of the
    configuration.

    Parameters
    ----------
    configuration : str
        One of :data:`CONFIGURATIONS`.
    n_trials : int
        Number of placements, >= 1.
    n_stars : int
        Guide stars per placement, >= 3 and >= the number of areas.
    step : float
        Lattice step, fraction of V.
    rng : Generator, int or None

    Returns
    -------
    ndarray, shape (n_trials, n_stars, 2)
        Focal-plane positions, units of V.
    """
    areas = configuration_areas(configuration)
    if not isinstance(n_trials, int | np.integer) or n_trials < 1:
        raise InputError(f"n_trials = {n_trials!r} must be an integer >= 1")
    if not isinstance(n_stars, int | np.integer) or n_stars < 3:
        raise InputError(
            f"n_stars = {n_stars!r} must be an integer >= 3 (triangles need three stars)"
        )
    if n_stars < len(areas):
        raise InputError(
            f"n_stars = {n_stars} cannot cover the {len(areas)} areas of {configuration!r}"
        )
    xy, area = lattice_points(step)
    keep = np.isin(area, areas)
    xy, area = xy[keep], area[keep]
    if n_stars > len(xy):
        raise InputError(f"n_stars = {n_stars} exceeds the {len(xy)} lattice points available")
    gen = _rng(rng)
    chosen: list[NDArray[np.int_]] = []
    have = 0
    while have < n_trials:
        m = max(2 * (n_trials - have), 64)
        idx = np.argpartition(gen.random((m, len(xy))), n_stars - 1, axis=1)[:, :n_stars]
        a = area[idx]
        ok = np.all([(a == k).any(axis=1) for k in areas], axis=0)
        chosen.append(idx[ok])
        have += int(ok.sum())
    idx = np.concatenate(chosen)[:n_trials]
    return xy[idx]


def focal_to_vectors(xy: ArrayLike, fov_rad: float) -> NDArray[np.float64]:
    """Camera-frame unit vectors of focal-plane points (gnomonic, see the module notes).

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Units of V.
    fov_rad : float
        Side V of the science square, rad, in (0, pi/2).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    if not (np.isfinite(fov_rad) and 0.0 < fov_rad < math.pi / 2):
        raise InputError(f"fov_rad = {fov_rad!r} must be in (0, pi/2)")
    p = _xy(xy) * (2.0 * math.tan(fov_rad / 2.0))
    v = np.concatenate([p, np.ones((*p.shape[:-1], 1))], axis=-1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def triangle_fov_ratio(xy: ArrayLike, configuration: str | None = None) -> NDArray[np.float64]:
    """The "average FOV ratio of the triangles formed by the guide stars" (Figs. 5-6).

    Mean area of the C(n, 3) triangles formed by the guide stars, over the total area of the
    attitude-determination areas of ``configuration`` (``None``: all four, 0.5708 V^2).

    Parameters
    ----------
    xy : array_like, shape (..., n, 2)
        Guide-star positions, units of V, n >= 3.

    Returns
    -------
    ndarray, shape (...)
    """
    p = _xy(xy)
    if p.ndim < 2 or p.shape[-2] < 3:
        raise InputError(f"need at least 3 guide stars for triangles, got shape {p.shape}")
    denom = attitude_area("four" if configuration is None else configuration)
    tri = np.array(list(combinations(range(p.shape[-2]), 3)))
    a, b, c = p[..., tri[:, 0], :], p[..., tri[:, 1], :], p[..., tri[:, 2], :]
    u, v = b - a, c - a
    area = 0.5 * np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])
    return area.mean(axis=-1) / denom


# ---------------------------------------------------------------------------------------------
# covariance (eqs. 1-5) and its probability


def _sigma(sigma_rad: float, name: str = "sigma_rad") -> float:
    try:
        s = float(sigma_rad)
    except (TypeError, ValueError):
        raise InputError(f"{name} = {sigma_rad!r} must be a number > 0") from None
    if not (np.isfinite(s) and s > 0):
        raise InputError(f"{name} = {sigma_rad!r} must be finite and > 0")
    return s


def batch_covariance(vectors: ArrayLike, sigma_rad: float) -> NDArray[np.float64]:
    """Attitude covariance P = F^-1 of many star sets at once (Lin et al. 2024, eqs. 1-3).

    Same formula as :func:`starsense.analysis.limits.fisher_matrix` and
    :func:`~starsense.analysis.limits.covariance`, batched: F = sum_i sigma^-2 (I - r_i r_i^T).

    Parameters
    ----------
    vectors : array_like, shape (M, N, 3)
        Camera-frame unit vectors of the guide stars.
    sigma_rad : float
        Per-axis measurement error of every star, rad.

    Returns
    -------
    ndarray, shape (M, 3, 3), rad^2
    """
    s = _sigma(sigma_rad)
    r = np.asarray(vectors, dtype=np.float64)
    n = r.shape[-2]
    f = (n * np.eye(3) - np.einsum("mni,mnj->mij", r, r)) / s**2
    return np.linalg.inv(f)


#: directions for the exact average over the sphere (3 dof) and the circle (2 dof)
_N_SPHERE = 4000  # 2000 used, one per antipodal pair
_N_CIRCLE = 256


def _chi3_cdf(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return erf(a / math.sqrt(2.0)) - math.sqrt(2.0 / math.pi) * a * np.exp(-0.5 * a * a)


def probability_within(
    cov_rad2: ArrayLike, threshold_rad: float, metric: str = "pointing"
) -> NDArray[np.float64]:
    """P(|delta phi| < t) for a zero-mean Gaussian attitude error of covariance P.

    With ``delta phi = L z`` (``L L^T = P``, z standard normal) and ``z = rho u`` (u uniform on
    the unit sphere, rho chi-distributed), ``P(|delta phi| < t) = E_u[F_chi(t / |L u|)]``; the
    average over u uses a Fibonacci lattice of 4000 directions (3 dof, ``metric="total"``) or
    256 equally spaced angles on the circle (2 dof, ``metric="pointing"``, the x-y block of P,
    Rayleigh/Hoyt distribution).

    Parameters
    ----------
    cov_rad2 : array_like, shape (..., 3, 3)
    threshold_rad : float
        t, rad.
    metric : {"total", "pointing"}

    Returns
    -------
    ndarray, shape (...)
    """
    _check_metric(metric)
    t = _sigma(threshold_rad, "threshold_rad")
    p = np.asarray(cov_rad2, dtype=np.float64)
    if metric == "pointing":
        p = p[..., :2, :2]
        ang = (np.arange(_N_CIRCLE) + 0.5) * (math.pi / _N_CIRCLE)  # u and -u are the same
        u2 = np.stack([np.cos(ang) ** 2, np.sin(ang) ** 2], axis=-1)
    else:
        u = fibonacci_sphere(_N_SPHERE)
        u2 = u[u[:, 2] > 0] ** 2  # u and -u are the same
    # in P's eigenbasis |L u|^2 = sum_k lambda_k u_k^2
    lam = np.linalg.eigvalsh(p)
    q = lam @ u2.T
    a = t / np.sqrt(q)
    cdf = 1.0 - np.exp(-0.5 * a * a) if metric == "pointing" else _chi3_cdf(a)
    return cdf.mean(axis=-1)


# ---------------------------------------------------------------------------------------------
# Monte Carlo


def _check_metric(metric: str) -> None:
    if metric not in METRICS:
        raise InputError(f"metric = {metric!r} is not known; choose one of {', '.join(METRICS)}")


def error_norm(rotvec: ArrayLike, metric: str = "pointing") -> NDArray[np.float64]:
    """Accuracy of trials from their camera-frame error rotation vectors (..., 3), rad."""
    _check_metric(metric)
    e = np.asarray(rotvec, dtype=np.float64)
    return np.linalg.norm(e[..., :2] if metric == "pointing" else e, axis=-1)


def batch_svd_attitude(body: ArrayLike, reference: ArrayLike) -> Rotation:
    """Equal-weight SVD (Kabsch / Markley 1988) solutions of many Wahba problems at once.

    The batched form of ``estimate_attitude(body, ref, sigma, method="svd")`` for equal sigmas:
    ``B = sum_i b_i r_i^T = U S V^T``, ``A = U diag(1, 1, det U det V) V^T``.

    Parameters
    ----------
    body, reference : array_like, shape (M, N, 3)
        Camera-frame and ICRS unit vectors.

    Returns
    -------
    Rotation, batch of M (ICRS -> camera)
    """
    b = np.asarray(body, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    mat = np.einsum("mni,mnj->mij", b, r)
    u, _, vt = np.linalg.svd(mat)
    d = np.sign(np.linalg.det(u) * np.linalg.det(vt))
    u[:, :, 2] *= d[:, None]
    return Rotation.from_matrix(u @ vt)


def _tangent_noise(
    vectors: NDArray[np.float64], z: NDArray[np.float64], sigma_rad: float
) -> NDArray[np.float64]:
    """Displace unit vectors (..., 3) by sigma * (z1 e1 + z2 e2) in their tangent planes."""
    helper = np.zeros_like(vectors)
    helper[..., 0] = 1.0  # guide stars are near +z, never along +x
    e1 = np.cross(vectors, helper)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(vectors, e1)
    out = vectors + sigma_rad * (z[..., 0:1] * e1 + z[..., 1:2] * e2)
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def monte_carlo_errors(
    vectors: ArrayLike,
    sigma_rad: float,
    rng: np.random.Generator | int | None = None,
    batched: bool = True,
    noise: ArrayLike | None = None,
    attitudes: Rotation | None = None,
) -> NDArray[np.float64]:
    """Attitude error of one noisy solve per star set.

    Each trial draws a true attitude A (uniform on SO(3)), takes the catalogue directions
    ``r_i = A^-1 b_i``, displaces the true camera-frame directions ``b_i`` by the measurement
    noise, solves for the attitude and returns ``small_rotation_angles(A, A_est)``.

    Parameters
    ----------
    vectors : array_like, shape (M, N, 3)
        True camera-frame unit vectors of the guide stars.
    sigma_rad : float
        Per-axis measurement error, rad.
    rng : Generator, int or None
    batched : bool
        True: :func:`batch_svd_attitude` (vectorised); False: one
        :func:`starsense.attitude.estimate_attitude` call per trial (slow, the reference).
    noise : array_like, shape (M, N, 2), optional
        Standard-normal tangent-plane deviates (common random numbers across sigmas).
    attitudes : Rotation of length M, optional
        True attitudes.

    Returns
    -------
    ndarray, shape (M, 3)
        Camera-frame error rotation vectors, rad.
    """
    s = _sigma(sigma_rad)
    b_true = np.asarray(vectors, dtype=np.float64)
    m, n = b_true.shape[:2]
    gen = _rng(rng)
    z = gen.standard_normal((m, n, 2)) if noise is None else np.asarray(noise, dtype=float)
    a_true = random_attitudes(m, gen) if attitudes is None else attitudes
    mats = a_true.as_matrix()  # rows: camera axes in ICRS; r = M^T b
    ref = np.einsum("mji,mnj->mni", mats, b_true)
    body = _tangent_noise(b_true, z, s)
    if batched:
        a_est = batch_svd_attitude(body, ref)
    else:
        from starsense.attitude import estimate_attitude

        a_est = Rotation.concatenate(
            [estimate_attitude(body[k], ref[k], s, method="svd").rotation for k in range(m)]
        )
    return (a_est * a_true.inv()).as_rotvec()


# ---------------------------------------------------------------------------------------------
# Table 1


@dataclass(frozen=True, eq=False)
class GuideStarTable:
    """Probability of accuracy better than a threshold, per configuration and sigma (Table 1).

    Attributes
    ----------
    sigma_arcsec : tuple of float
        Per-axis measurement errors, arcsec (rows).
    probability_mc, probability_analytic : dict str -> ndarray (n_sigma,)
        Monte Carlo fraction of trials with error < threshold, and the mean over the same
        placements of the Gaussian prediction from P = F^-1; 0-1.
    triangle_ratio : dict str -> ndarray (n_trials,)
        Average FOV ratio of the triangles of each placement (denominator: the
        configuration's own areas).
    placements : dict str -> ndarray (n_trials, n_stars, 2)
    threshold_arcsec, fov_deg, step, n_stars, n_trials, metric, seed : settings
    elapsed_s : float
        Wall-clock time of the whole table, s.
    """

    sigma_arcsec: tuple[float, ...]
    probability_mc: dict[str, NDArray[np.float64]]
    probability_analytic: dict[str, NDArray[np.float64]]
    triangle_ratio: dict[str, NDArray[np.float64]] = field(repr=False)
    placements: dict[str, NDArray[np.float64]] = field(repr=False)
    threshold_arcsec: float = 0.1
    fov_deg: float = PAPER_FOV_DEG
    step: float = PAPER_STEP
    n_stars: int = 5
    n_trials: int = 10_000
    metric: str = "pointing"
    seed: int = 0
    elapsed_s: float = 0.0

    def as_dict(self) -> dict:
        """JSON-ready summary (the CLI's ``--json`` payload)."""
        return {
            "sigma_arcsec": list(self.sigma_arcsec),
            "probability": {k: v.tolist() for k, v in self.probability_mc.items()},
            "probability_analytic": {k: v.tolist() for k, v in self.probability_analytic.items()},
            "paper_percent": {k: list(PAPER_TABLE1_PERCENT[k]) for k in self.probability_mc}
            if tuple(self.sigma_arcsec) == PAPER_SIGMAS_ARCSEC
            else None,
            "threshold_arcsec": self.threshold_arcsec,
            "fov_deg": self.fov_deg,
            "step": self.step,
            "n_stars": self.n_stars,
            "n_trials": self.n_trials,
            "metric": self.metric,
            "seed": self.seed,
            "elapsed_s": self.elapsed_s,
        }


def simulate_table1(
    sigmas_arcsec: ArrayLike = PAPER_SIGMAS_ARCSEC,
    configurations: tuple[str, ...] | list[str] | None = None,
    n_trials: int = 10_000,
    fov_deg: float = PAPER_FOV_DEG,
    threshold_arcsec: float = 0.1,
    n_stars: int = 5,
    step: float = PAPER_STEP,
    metric: str = "pointing",
    seed: int = 0,
) -> GuideStarTable:
    """Lin et al. 2024, Table 1: P(accuracy < threshold) per configuration and sigma.

    For each configuration, ``n_trials`` placements (:func:`sample_placements`), each with one
    true attitude and one standard-normal noise draw reused (scaled) for every sigma; the Monte
    Carlo solves with :func:`batch_svd_attitude`, the analytic column averages
    :func:`probability_within` of P = F^-1 (eqs. 1-3) over the same placements. Child seeds
    derive from ``seed`` (one per configuration), so the table is reproducible bit for bit.

    Parameters
    ----------
    sigmas_arcsec : array_like of float
        Per-axis measurement errors, arcsec, > 0.
    configurations : sequence of str or None
        Default: all five, in Table 1's order.
    n_trials : int
        Placements (and noise draws) per configuration.
    fov_deg : float
        Side V of the science field, deg (default: the paper's 2048 x 2 arcsec camera).
    threshold_arcsec : float
        Accuracy requirement, arcsec (the paper: 0.1).
    n_stars, step : int, float
        Guide stars per placement (paper: 5) and lattice step, fraction of V (paper: 0.07).
    metric : {"total", "pointing"}
        Accuracy = norm of the whole error rotation vector, or of its cross-boresight part.
    seed : int
        Root seed.

    Returns
    -------
    GuideStarTable
    """
    start = time.perf_counter()
    sig = np.atleast_1d(np.asarray(sigmas_arcsec, dtype=np.float64))
    if sig.ndim != 1 or sig.size == 0:
        raise InputError("sigmas_arcsec must be a non-empty list of numbers")
    for s in sig:
        _sigma(s, "sigma_arcsec")
    thr = _sigma(threshold_arcsec, "threshold_arcsec")
    _check_metric(metric)
    if not (np.isfinite(fov_deg) and 0.0 < fov_deg < 90.0):
        raise InputError(f"fov_deg = {fov_deg!r} must be in (0, 90)")
    configs = tuple(CONFIGURATIONS) if configurations is None else tuple(configurations)
    for c in configs:
        configuration_areas(c)
    fov_rad = math.radians(fov_deg)
    thr_rad = thr * ARCSEC_RAD
    children = np.random.SeedSequence(seed).spawn(len(configs))
    p_mc: dict[str, NDArray[np.float64]] = {}
    p_an: dict[str, NDArray[np.float64]] = {}
    ratios: dict[str, NDArray[np.float64]] = {}
    places: dict[str, NDArray[np.float64]] = {}
    for c, child in zip(configs, children, strict=True):
        gen = np.random.default_rng(child)
        xy = sample_placements(c, n_trials, n_stars, step, gen)
        vec = focal_to_vectors(xy, fov_rad)
        z = gen.standard_normal((n_trials, n_stars, 2))
        att = random_attitudes(n_trials, gen)
        cov1 = batch_covariance(vec, 1.0)  # P scales with sigma^2
        mc, an = [], []
        for s in sig:
            s_rad = s * ARCSEC_RAD
            err = monte_carlo_errors(vec, s_rad, noise=z, attitudes=att)
            mc.append(float(np.mean(error_norm(err, metric) < thr_rad)))
            an.append(float(np.mean(probability_within(cov1 * s_rad**2, thr_rad, metric))))
        p_mc[c], p_an[c] = np.array(mc), np.array(an)
        ratios[c] = triangle_fov_ratio(xy, c)
        places[c] = xy
    return GuideStarTable(
        sigma_arcsec=tuple(float(s) for s in sig),
        probability_mc=p_mc,
        probability_analytic=p_an,
        triangle_ratio=ratios,
        placements=places,
        threshold_arcsec=thr,
        fov_deg=float(fov_deg),
        step=step,
        n_stars=n_stars,
        n_trials=n_trials,
        metric=metric,
        seed=seed,
        elapsed_s=time.perf_counter() - start,
    )
