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
    * Identification: the triangle algorithm runs in the loop (:func:`identify_triangles`):
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
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from itertools import combinations, permutations

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
#: how a quoted measurement error relates to the per-axis standard deviation
SIGMA_KINDS = {"1sigma": 1.0, "3sigma": 3.0}


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
# triangle identification in the loop

#: identification outcome codes of :func:`identify_triangles`
ID_FAILED, ID_CORRECT, ID_WRONG = 0, 1, 2
#: default side tolerance, in standard deviations of a measured inter-star angle
ID_TOLERANCE_SIGMA = 3.0


def _pair_angles(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Inter-star angles (..., N, N) of unit vectors (..., N, 3), rad (chord form, exact)."""
    chord = np.linalg.norm(v[..., :, None, :] - v[..., None, :, :], axis=-1)
    return 2.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0))


def _handedness(v: NDArray[np.float64], tri: NDArray[np.int_]) -> NDArray[np.float64]:
    """Sign of the triple product of the triangles ``tri`` (T, 3) of each set (..., N, 3)."""
    a, b, c = v[..., tri[:, 0], :], v[..., tri[:, 1], :], v[..., tri[:, 2], :]
    return np.sign(np.einsum("...i,...i->...", a, np.cross(b, c)))


def identify_triangles(
    measured: ArrayLike, catalogue: ArrayLike, tolerance_rad: float
) -> NDArray[np.int_]:
    """Triangle star identification of many small star sets at once (Liebe 1992), with
    verification by the remaining stars.

    The catalogue of each trial is its own guide stars (Lin et al. 2024, sec. 4: "the reference
    star catalog does not include interfering stars"). The measured triangles are tried in
    turn; a catalogue triangle (an ordered vertex triple) is a candidate when its three sides
    match the measured ones within ``tolerance_rad`` and it has the same handedness (the sign of
    the triple product, which a rotation keeps). A candidate is verified when every remaining
    measured star has a remaining catalogue star whose angles to the triangle's three vertices
    match within the tolerance. The first measured triangle with exactly one verified
    candidate decides; a trial where no triangle does is a failure. The algorithm sees only
    inter-star angles, never the star indices, so the outcome is compared to the truth (star
    ``i`` measured is catalogue star ``i``) only at the end.

    Parameters
    ----------
    measured : array_like, shape (M, N, 3)
        Measured (noisy) camera-frame unit vectors, N >= 3.
    catalogue : array_like, shape (M, N, 3)
        The guide stars' true directions in any one frame per trial (angles are all that
        matter).
    tolerance_rad : float
        Largest accepted difference between a measured and a catalogue angle, rad.

    Returns
    -------
    ndarray of int, shape (M,)
        :data:`ID_CORRECT`, :data:`ID_WRONG` or :data:`ID_FAILED` per trial.
    """
    tol = _sigma(tolerance_rad, "tolerance_rad")
    bm = np.asarray(measured, dtype=np.float64)
    bc = np.asarray(catalogue, dtype=np.float64)
    if bm.ndim != 3 or bm.shape[-1] != 3 or bm.shape != bc.shape:
        raise InputError(
            f"measured and catalogue must both have shape (M, N, 3), got {bm.shape} and {bc.shape}"
        )
    m, n = bm.shape[:2]
    if n < 3:
        raise InputError(f"triangle identification needs at least 3 guide stars, got {n}")
    combos = np.array(list(combinations(range(n), 3)))  # measured triangles, tried in order
    perms = np.array(list(permutations(range(n), 3)))  # catalogue ordered triangles
    dm, dc = _pair_angles(bm), _pair_angles(bc)
    hm, hc = _handedness(bm, combos), _handedness(bc, perms)
    side_m = np.stack(
        [
            dm[:, combos[:, 0], combos[:, 1]],
            dm[:, combos[:, 0], combos[:, 2]],
            dm[:, combos[:, 1], combos[:, 2]],
        ],
        axis=-1,
    )  # (M, T, 3)
    side_c = np.stack(
        [
            dc[:, perms[:, 0], perms[:, 1]],
            dc[:, perms[:, 0], perms[:, 2]],
            dc[:, perms[:, 1], perms[:, 2]],
        ],
        axis=-1,
    )  # (M, P, 3)
    match = np.all(np.abs(side_m[:, :, None, :] - side_c[:, None, :, :]) <= tol, axis=-1)
    match &= hm[:, :, None] == hc[:, None, :]
    # verification of the (sparse) candidates by the remaining stars
    k, t, p = np.nonzero(match)
    verified = np.ones(len(k), dtype=bool)
    if n > 3 and len(k):
        others = np.array([[j for j in range(n) if j not in c] for c in combos])  # (T, N-3)
        rest_m = others[t]  # (K, N-3) remaining measured stars
        in_p = np.zeros((len(k), n), dtype=bool)
        in_p[np.arange(len(k))[:, None], perms[p]] = True
        # angles from each remaining measured star to the measured triangle's vertices
        am = dm[k[:, None, None], rest_m[:, :, None], combos[t][:, None, :]]  # (K, N-3, 3)
        # angles from every catalogue star to the catalogue triangle's vertices
        ac = dc[k[:, None, None], np.arange(n)[None, :, None], perms[p][:, None, :]]  # (K, N, 3)
        ok = np.all(np.abs(am[:, :, None, :] - ac[:, None, :, :]) <= tol, axis=-1)
        ok &= ~in_p[:, None, :]  # (K, N-3, N)
        verified = np.all(ok.any(axis=-1), axis=-1)
    n_verified = np.zeros((m, len(combos)), dtype=int)
    np.add.at(n_verified, (k[verified], t[verified]), 1)
    decided = n_verified == 1
    has = decided.any(axis=1)
    first = np.argmax(decided, axis=1)
    out = np.full(m, ID_FAILED, dtype=int)
    if has.any():
        sel = verified & (t == first[k]) & has[k]
        kk, pp = k[sel], p[sel]
        correct = np.all(perms[pp] == combos[first[kk]], axis=-1)
        out[kk] = np.where(correct, ID_CORRECT, ID_WRONG)
    return out


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
    success : dict str -> ndarray of bool (n_sigma, n_trials)
        Per trial: identified correctly (when ``identify``) and error below the threshold.
    identified : dict str -> ndarray (n_sigma,)
        Fraction of trials whose stars the triangle algorithm identified correctly (1 when
        ``identify`` is False).
    threshold_arcsec, fov_deg, step, n_stars, n_trials, metric, seed, identify, sigma_kind :
        settings
    elapsed_s : float
        Wall-clock time of the whole table, s.
    """

    sigma_arcsec: tuple[float, ...]
    probability_mc: dict[str, NDArray[np.float64]]
    probability_analytic: dict[str, NDArray[np.float64]]
    triangle_ratio: dict[str, NDArray[np.float64]] = field(repr=False)
    placements: dict[str, NDArray[np.float64]] = field(repr=False)
    success: dict[str, NDArray[np.bool_]] = field(repr=False, default_factory=dict)
    identified: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    threshold_arcsec: float = 0.1
    fov_deg: float = PAPER_FOV_DEG
    step: float = PAPER_STEP
    n_stars: int = 5
    n_trials: int = 10_000
    metric: str = "pointing"
    seed: int = 0
    identify: bool = True
    sigma_kind: str = "1sigma"
    elapsed_s: float = 0.0

    def by_triangle_ratio(
        self, configuration: str, sigma_arcsec: float, n_bins: int = 10
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int_]]:
        """Probability of success against the triangle ratio (Lin et al. 2024, Figs. 5-6).

        Trials are binned on quantiles of their average FOV ratio of the triangles, so every bin
        holds about the same number of trials.

        Returns
        -------
        ratio : ndarray (n_bins,)
            Mean triangle ratio of each bin.
        probability : ndarray (n_bins,)
            Fraction of the bin's trials that succeeded, 0-1.
        count : ndarray of int (n_bins,)
        """
        if configuration not in self.success:
            raise InputError(f"configuration {configuration!r} is not in this table")
        try:
            i = [round(x, 12) for x in self.sigma_arcsec].index(round(float(sigma_arcsec), 12))
        except ValueError:
            raise InputError(
                f"sigma {sigma_arcsec!r} arcsec is not in this table ({list(self.sigma_arcsec)})"
            ) from None
        if not isinstance(n_bins, int) or n_bins < 1:
            raise InputError(f"n_bins = {n_bins!r} must be an integer >= 1")
        r = self.triangle_ratio[configuration]
        ok = self.success[configuration][i]
        order = np.argsort(r, kind="stable")
        groups = np.array_split(order, n_bins)
        ratio = np.array([r[g].mean() for g in groups])
        prob = np.array([ok[g].mean() for g in groups])
        count = np.array([len(g) for g in groups])
        return ratio, prob, count

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
            "identify": self.identify,
            "identified": {k: v.tolist() for k, v in self.identified.items()},
            "sigma_kind": self.sigma_kind,
            "elapsed_s": self.elapsed_s,
        }


def _check_sigmas(sigmas_arcsec: ArrayLike, sigma_kind: str) -> tuple[NDArray[np.float64], float]:
    """Validated sigmas (arcsec, 1-D) and the standard deviation per quoted sigma."""
    sig = np.atleast_1d(np.asarray(sigmas_arcsec, dtype=np.float64))
    if sig.ndim != 1 or sig.size == 0:
        raise InputError("sigmas_arcsec must be a non-empty list of numbers")
    for s in sig:
        _sigma(s, "sigma_arcsec")
    if sigma_kind not in SIGMA_KINDS:
        raise InputError(
            f"sigma_kind = {sigma_kind!r} is not known; choose one of {', '.join(SIGMA_KINDS)}"
        )
    return sig, 1.0 / SIGMA_KINDS[sigma_kind]


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
    identify: bool = True,
    sigma_kind: str = "1sigma",
    id_tolerance_sigma: float = ID_TOLERANCE_SIGMA,
    progress=None,
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
    identify : bool
        Run triangle identification in the loop (:func:`identify_triangles`); a trial
        succeeds only if its stars are identified correctly.
    sigma_kind : {"1sigma", "3sigma"}
        ``sigmas_arcsec`` are per-axis standard deviations, or 3-sigma bounds (standard
        deviation sigma / 3), see the module notes.
    id_tolerance_sigma : float
        Side tolerance of the identification, in standard deviations of a measured
        inter-star angle (sqrt(2) x the per-axis standard deviation).
    progress : callable(label, done, total), optional
        Called after each (configuration, sigma) cell.

    Returns
    -------
    GuideStarTable
    """
    start = time.perf_counter()
    sig, sd_per_quoted = _check_sigmas(sigmas_arcsec, sigma_kind)
    thr = _sigma(threshold_arcsec, "threshold_arcsec")
    _check_metric(metric)
    k_tol = _sigma(id_tolerance_sigma, "id_tolerance_sigma")
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
    succ: dict[str, NDArray[np.bool_]] = {}
    ident: dict[str, NDArray[np.float64]] = {}
    done = 0
    for c, child in zip(configs, children, strict=True):
        gen = np.random.default_rng(child)
        xy = sample_placements(c, n_trials, n_stars, step, gen)
        vec = focal_to_vectors(xy, fov_rad)
        z = gen.standard_normal((n_trials, n_stars, 2))
        att = random_attitudes(n_trials, gen)
        cov1 = batch_covariance(vec, 1.0)  # P scales with sigma^2
        an, ok_rows, id_rows = [], [], []
        for s in sig:
            s_rad = s * ARCSEC_RAD * sd_per_quoted
            err = monte_carlo_errors(vec, s_rad, noise=z, attitudes=att)
            ok = error_norm(err, metric) < thr_rad
            if identify:
                measured = _tangent_noise(vec, z, s_rad)  # the same noisy stars the solve used
                found = identify_triangles(measured, vec, k_tol * math.sqrt(2.0) * s_rad)
                ok &= found == ID_CORRECT
                id_rows.append(float(np.mean(found == ID_CORRECT)))
            else:
                id_rows.append(1.0)
            ok_rows.append(ok)
            an.append(float(np.mean(probability_within(cov1 * s_rad**2, thr_rad, metric))))
            if progress is not None:
                done += 1
                progress("Table 1 cells", done, len(configs) * len(sig))
        succ[c] = np.array(ok_rows)
        p_mc[c], p_an[c] = succ[c].mean(axis=1), np.array(an)
        ident[c] = np.array(id_rows)
        ratios[c] = triangle_fov_ratio(xy, c)
        places[c] = xy
    return GuideStarTable(
        sigma_arcsec=tuple(float(s) for s in sig),
        probability_mc=p_mc,
        probability_analytic=p_an,
        triangle_ratio=ratios,
        placements=places,
        success=succ,
        identified=ident,
        threshold_arcsec=thr,
        fov_deg=float(fov_deg),
        step=step,
        n_stars=n_stars,
        n_trials=n_trials,
        metric=metric,
        seed=seed,
        identify=bool(identify),
        sigma_kind=sigma_kind,
        elapsed_s=time.perf_counter() - start,
    )


# ---------------------------------------------------------------------------------------------
# guide-star selection (item 4) and real fields (sec. 5, Tables 3-4)

#: selection criteria of :func:`select_guide_stars`
CRITERIA = ("trace", "rules", "brightest")
#: area combinations of each configuration on a four-area layout (sec. 5: "the average value of
#: all possible combinations")
LAYOUT_COMBINATIONS: dict[str, tuple[tuple[int, ...], ...]] = {
    "one": ((1,), (2,), (3,), (4,)),
    "two_adjacent": ((1, 2), (2, 3), (3, 4), (4, 1)),
    "two_symmetric": ((1, 3), (2, 4)),
    "three": ((1, 2, 3), (2, 3, 4), (3, 4, 1), (4, 1, 2)),
    "four": ((1, 2, 3, 4),),
}
#: Lin et al. 2024, Tables 3 and 4: average attitude accuracy (arcsec) at average measurement
#: errors 0.2 and 0.05 arcsec, 1.6 deg patterns (DSS images)
PAPER_FIELDS: dict[str, dict] = {
    "table3": {
        "center_deg": (150.0, 0.0),
        "accuracy_arcsec": {
            0.2: {
                "one": 6.51,
                "two_adjacent": 0.34,
                "two_symmetric": 0.21,
                "three": 0.21,
                "four": 0.08,
            },
            0.05: {
                "one": 18.02,
                "two_adjacent": 0.13,
                "two_symmetric": 0.06,
                "three": 0.10,
                "four": 0.04,
            },
        },
    },
    "table4": {
        "center_deg": (240.0, -80.0),
        "accuracy_arcsec": {
            0.2: {
                "one": 34.04,
                "two_adjacent": 0.42,
                "two_symmetric": 0.21,
                "three": 0.26,
                "four": 0.07,
            },
            0.05: {
                "one": 1.17,
                "two_adjacent": 0.21,
                "two_symmetric": 0.03,
                "three": 0.07,
                "four": 0.03,
            },
        },
    },
}
#: the paper's star patterns: lens-circle diameters, deg (Table 2)
PAPER_PATTERN_FOVS_DEG = (1.6, 0.4)


@dataclass(frozen=True, eq=False)
class GuideStarSelection:
    """Guide stars chosen from the stars in some attitude-determination areas.

    Attributes
    ----------
    status : str
        ``"ok"``, ``"no_stars"`` (no catalogue star in the areas) or ``"too_few_stars"`` (1-2:
        no triangle, no attitude).
    indices : ndarray of int
        Chosen stars, indices into the arrays given to :func:`select_guide_stars`.
    n_candidates : int
        Stars in the areas (before the brightness cut to ``max_candidates``).
    areas_covered : int
        Areas holding at least one chosen star.
    triangle_ratio : float
        Average FOV ratio of the chosen stars' triangles (NaN below 3 stars).
    predicted_rad : float
        ``sqrt(trace P)`` of the metric's block at ``sigma_rad`` (NaN below 3 stars).
    criterion : str
    """

    status: str
    indices: NDArray[np.int_]
    n_candidates: int
    areas_covered: int
    triangle_ratio: float
    predicted_rad: float
    criterion: str

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def _metric_block(cov: NDArray[np.float64], metric: str) -> NDArray[np.float64]:
    return cov[..., :2, :2] if metric == "pointing" else cov


def select_guide_stars(
    xy: ArrayLike,
    magnitude: ArrayLike,
    layout,
    areas: tuple[int, ...] | None = None,
    n_stars: int = 5,
    criterion: str = "trace",
    sigma_rad: float = 0.1 * ARCSEC_RAD,
    metric: str = "pointing",
    max_candidates: int = 20,
) -> GuideStarSelection:
    """Choose ``n_stars`` guide stars among the stars in some areas of a layout.

    Criteria
        ``"trace"`` (the direct one): the combination with the smallest trace of the attitude
        covariance (eqs. 1-3; the x-y block for ``metric="pointing"``). ``"rules"`` (the paper's
        sec. 4 rules): cover as many areas as possible, then the largest average FOV ratio of
        the triangles. ``"brightest"``: the ``n_stars`` brightest, the baseline. Combinations
        are enumerated exhaustively among the ``max_candidates`` brightest stars in the areas
        (C(20, 5) = 15,504 at the defaults, vectorised).

    Parameters
    ----------
    xy : array_like, shape (N, 2)
        Stars' tangent-plane coordinates (:mod:`starsense.geometry.areas`).
    magnitude : array_like, shape (N,)
        Brightness order (smaller is brighter); NaN sorts last.
    layout : AreaLayout
    areas : tuple of int or None
        1-based area numbers to use (default: all).
    n_stars : int
        Guide stars wanted, >= 3; fewer are used when the areas hold fewer.
    criterion, sigma_rad, metric, max_candidates : see above.

    Returns
    -------
    GuideStarSelection
    """
    from starsense.geometry.areas import tangent_to_vectors

    p = _xy(xy)
    if p.ndim != 2:
        raise InputError(f"xy must have shape (N, 2), got {p.shape}")
    mag = np.asarray(magnitude, dtype=np.float64)
    if mag.shape != (len(p),):
        raise InputError(f"magnitude must have shape ({len(p)},), got {mag.shape}")
    if criterion not in CRITERIA:
        raise InputError(f"criterion = {criterion!r} is not known; choose one of {CRITERIA}")
    _check_metric(metric)
    s = _sigma(sigma_rad)
    if not isinstance(n_stars, int | np.integer) or n_stars < 3:
        raise InputError(
            f"n_stars = {n_stars!r} must be an integer >= 3 (triangles need three stars)"
        )
    if not isinstance(max_candidates, int | np.integer) or max_candidates < n_stars:
        raise InputError(f"max_candidates = {max_candidates!r} must be an integer >= n_stars")
    chosen_areas = tuple(range(1, len(layout.areas) + 1)) if areas is None else tuple(areas)
    for k in chosen_areas:
        if not 1 <= k <= len(layout.areas):
            raise InputError(f"area number {k} is not in the layout (1-{len(layout.areas)})")
    which = layout.index(p) if len(p) else np.zeros(0, dtype=int)
    cand = np.flatnonzero(np.isin(which, chosen_areas))
    n_cand = len(cand)
    cand = cand[np.argsort(np.where(np.isnan(mag[cand]), np.inf, mag[cand]), kind="stable")]
    cand = cand[:max_candidates]
    nan = float("nan")
    if n_cand == 0:
        return GuideStarSelection("no_stars", cand, 0, 0, nan, nan, criterion)
    if n_cand < 3:
        covered = len(set(which[cand].tolist()))
        return GuideStarSelection("too_few_stars", cand, n_cand, covered, nan, nan, criterion)
    n = min(n_stars, len(cand))
    combos = (
        np.arange(n)[None, :]
        if criterion == "brightest"
        else np.array(list(combinations(range(len(cand)), n)))
    )
    idx = cand[combos]  # (C, n)
    denom = layout.subset_area(chosen_areas)
    best = 0
    if len(combos) > 1:
        if criterion == "trace":
            vec = tangent_to_vectors(p[idx])
            tr = np.trace(_metric_block(batch_covariance(vec, s), metric), axis1=-2, axis2=-1)
            best = int(np.argmin(tr))
        else:  # rules: coverage first, then the triangle ratio
            covered = np.zeros(len(combos), dtype=int)
            for k in chosen_areas:
                covered += (which[idx] == k).any(axis=1)
            ratio = triangle_fov_ratio(p[idx]) * attitude_area("four") / denom
            best = int(np.lexsort((-ratio, -covered))[0])
    sel = idx[best]
    cov = batch_covariance(tangent_to_vectors(p[sel])[None], s)[0]
    return GuideStarSelection(
        status="ok",
        indices=sel,
        n_candidates=n_cand,
        areas_covered=len(set(which[sel].tolist())),
        triangle_ratio=float(triangle_fov_ratio(p[sel]) * attitude_area("four") / denom),
        predicted_rad=float(np.sqrt(np.trace(_metric_block(cov, metric)))),
        criterion=criterion,
    )


@dataclass(frozen=True, eq=False)
class FieldAccuracy:
    """Average attitude accuracy of a real star field per configuration (Tables 3-4).

    Attributes
    ----------
    center_deg, lens_fov_deg, catalog, band, max_mag : the field and the stars used
    stars_per_area : tuple of int
        Catalogue stars in areas 1-4.
    sigma_arcsec : tuple of float
    accuracy_arcsec : dict str -> ndarray (n_sigma,)
        Mean attitude error (Monte Carlo, the metric's norm) averaged over the configuration's
        usable area combinations; NaN when none is usable.
    predicted_arcsec : dict str -> ndarray (n_sigma,)
        The same average of ``sqrt(trace P)`` (eqs. 1-3).
    usable : dict str -> tuple (usable, total)
        Area combinations with at least three stars, and all combinations.
    selections : dict str -> list of (areas, GuideStarSelection)
    """

    center_deg: tuple[float, float]
    lens_fov_deg: float
    catalog: str
    band: str
    max_mag: float | None
    stars_per_area: tuple[int, ...]
    sigma_arcsec: tuple[float, ...]
    accuracy_arcsec: dict[str, NDArray[np.float64]]
    predicted_arcsec: dict[str, NDArray[np.float64]]
    usable: dict[str, tuple[int, int]]
    selections: dict[str, list] = field(repr=False)
    criterion: str = "trace"
    n_trials: int = 2000
    metric: str = "pointing"
    sigma_kind: str = "1sigma"

    def as_dict(self) -> dict:
        def num(x: float) -> float | None:
            return None if not np.isfinite(x) else float(x)

        return {
            "center_deg": list(self.center_deg),
            "lens_fov_deg": self.lens_fov_deg,
            "catalog": self.catalog,
            "band": self.band,
            "max_mag": self.max_mag,
            "stars_per_area": list(self.stars_per_area),
            "sigma_arcsec": list(self.sigma_arcsec),
            "accuracy_arcsec": {k: [num(x) for x in v] for k, v in self.accuracy_arcsec.items()},
            "predicted_arcsec": {k: [num(x) for x in v] for k, v in self.predicted_arcsec.items()},
            "usable_combinations": {k: list(v) for k, v in self.usable.items()},
            "guide_stars": {
                k: [
                    {
                        "areas": list(a),
                        "status": s.status,
                        "n_candidates": s.n_candidates,
                        "n_guide_stars": len(s.indices) if s.ok else 0,
                        "areas_covered": s.areas_covered,
                        "triangle_ratio": num(s.triangle_ratio),
                    }
                    for a, s in v
                ]
                for k, v in self.selections.items()
            },
            "criterion": self.criterion,
            "n_trials": self.n_trials,
            "metric": self.metric,
            "sigma_kind": self.sigma_kind,
        }


def lin_layout(lens_fov_deg: float):
    """The four-segment layout of a lens circle of diameter ``lens_fov_deg`` (Table 2's FOV)."""
    from starsense.geometry.areas import AreaLayout

    if not (np.isfinite(lens_fov_deg) and 0 < lens_fov_deg < 60):
        raise InputError(f"lens_fov_deg = {lens_fov_deg!r} must be in (0, 60) deg")
    return AreaLayout.lin2024(math.tan(math.radians(lens_fov_deg) / 2.0) / math.sqrt(2.0))


def field_stars(
    catalog,
    center_deg: tuple[float, float],
    layout,
    roll_deg: float = 0.0,
    max_mag: float | None = None,
) -> tuple[NDArray[np.int_], NDArray[np.float64], NDArray[np.float64], str]:
    """The catalogue stars that can fall in a layout's areas at one pointing.

    Returns ``(rows, xy, mag, band)``: catalogue row indices, tangent-plane positions and
    magnitudes of the stars within the layout's outermost vertex of the boresight
    ``center_deg`` (RA, Dec) at roll ``roll_deg``, and the magnitude band used (V, else G,
    else Hp).
    """
    from starsense.geometry.areas import vectors_to_tangent
    from starsense.geometry.attitude import attitude_from_radec_roll

    try:
        ra, dec = (float(c) for c in center_deg)
    except (TypeError, ValueError):
        raise InputError(f"center {center_deg!r} must be (RA, Dec) in degrees") from None
    if not (np.isfinite(ra) and np.isfinite(dec) and -90 <= dec <= 90):
        raise InputError(f"center {center_deg!r}: RA must be finite and Dec within [-90, 90]")
    band = next((b for b in ("V", "G", "Hp") if b in catalog.bands), None)
    if band is None:
        raise InputError(f"catalogue {catalog.name} has none of the bands V, G, Hp")
    att = attitude_from_radec_roll(math.radians(ra), math.radians(dec), math.radians(roll_deg))
    reach = max(float(np.hypot(*a.vertices.T).max()) for a in layout.areas)
    radius = math.atan(reach) * 1.0001
    rows = np.asarray(catalog.cone(att.inv().apply([0.0, 0.0, 1.0]), radius), dtype=int)
    mag = np.asarray(catalog.mags[band], dtype=np.float64)[rows]
    if max_mag is not None:
        keep = mag <= max_mag
        rows, mag = rows[keep], mag[keep]
    xy = vectors_to_tangent(att.apply(catalog.vectors[rows]).reshape(-1, 3))
    return rows, xy, mag, band


def field_accuracy(
    catalog,
    center_deg: tuple[float, float],
    lens_fov_deg: float = 1.6,
    sigmas_arcsec: ArrayLike = (0.2, 0.05),
    configurations: tuple[str, ...] | list[str] | None = None,
    n_stars: int = 5,
    criterion: str = "trace",
    max_mag: float | None = None,
    n_trials: int = 2000,
    metric: str = "pointing",
    sigma_kind: str = "1sigma",
    roll_deg: float = 0.0,
    seed: int = 0,
) -> FieldAccuracy:
    """Lin et al. 2024, Tables 3-4: average accuracy of a real field per configuration.

    For every area combination of every configuration (:data:`LAYOUT_COMBINATIONS`), guide
    stars are chosen (:func:`select_guide_stars`) among the catalogue stars in those areas, and
    ``n_trials`` noisy solves (:func:`monte_carlo_errors`) give the mean error; combinations
    with fewer than three stars are not usable and are counted, not averaged. The layout is the
    four segments around the square inscribed in the lens circle (``lens_fov_deg`` is the
    pattern's field, Table 2: 1.6 or 0.4 deg).

    Returns
    -------
    FieldAccuracy
    """
    sig, sd = _check_sigmas(sigmas_arcsec, sigma_kind)
    _check_metric(metric)
    if not isinstance(n_trials, int | np.integer) or n_trials < 1:
        raise InputError(f"n_trials = {n_trials!r} must be an integer >= 1")
    configs = tuple(CONFIGURATIONS) if configurations is None else tuple(configurations)
    for c in configs:
        configuration_areas(c)
    layout = lin_layout(lens_fov_deg)
    _, xy, mag, band = field_stars(catalog, center_deg, layout, roll_deg, max_mag)
    which = layout.index(xy) if len(xy) else np.zeros(0, dtype=int)
    per_area = tuple(int(np.sum(which == k)) for k in (1, 2, 3, 4))
    gen = np.random.default_rng(seed)
    from starsense.geometry.areas import tangent_to_vectors

    acc: dict[str, NDArray[np.float64]] = {}
    pred: dict[str, NDArray[np.float64]] = {}
    usable: dict[str, tuple[int, int]] = {}
    sels: dict[str, list] = {}
    for c in configs:
        combos = LAYOUT_COMBINATIONS[c]
        rows_acc, rows_pred, chosen = [], [], []
        for areas in combos:
            sel = select_guide_stars(
                xy, mag, layout, areas, n_stars, criterion, 0.1 * ARCSEC_RAD, metric
            )
            chosen.append((areas, sel))
            if not sel.ok:
                continue
            vec = tangent_to_vectors(xy[sel.indices])
            vecs = np.broadcast_to(vec, (n_trials, *vec.shape))
            z = gen.standard_normal((n_trials, len(vec), 2))
            att = random_attitudes(n_trials, gen)
            cov1 = batch_covariance(vec[None], 1.0)[0]
            a_row, p_row = [], []
            for s in sig:
                s_rad = s * ARCSEC_RAD * sd
                err = monte_carlo_errors(vecs, s_rad, noise=z, attitudes=att)
                a_row.append(float(np.mean(error_norm(err, metric))) / ARCSEC_RAD)
                p_row.append(
                    float(np.sqrt(np.trace(_metric_block(cov1, metric)))) * s_rad / ARCSEC_RAD
                )
            rows_acc.append(a_row)
            rows_pred.append(p_row)
        usable[c] = (len(rows_acc), len(combos))
        nan_row = np.full(len(sig), np.nan)
        acc[c] = np.mean(rows_acc, axis=0) if rows_acc else nan_row
        pred[c] = np.mean(rows_pred, axis=0) if rows_pred else nan_row
        sels[c] = chosen
    return FieldAccuracy(
        center_deg=(float(center_deg[0]), float(center_deg[1])),
        lens_fov_deg=float(lens_fov_deg),
        catalog=str(catalog.name),
        band=band,
        max_mag=max_mag,
        stars_per_area=per_area,
        sigma_arcsec=tuple(float(s) for s in sig),
        accuracy_arcsec=acc,
        predicted_arcsec=pred,
        usable=usable,
        selections=sels,
        criterion=criterion,
        n_trials=int(n_trials),
        metric=metric,
        sigma_kind=sigma_kind,
    )
