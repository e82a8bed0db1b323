"""Where each star lies during the exposure, and how that moves with the attitude and the rate.

Conventions of :mod:`starsense.render.scene`: the attitude ``A`` is the mid-exposure rotation
from ICRS to the camera frame, the body rate ``w`` (camera frame, rad/s) is constant, and at
time ``tau`` from mid-exposure a star of ICRS direction ``v`` lies along ``R(-w tau) A v``,
projected by the sensor (pinhole and distortion). The attitude is perturbed in the camera frame,
``A(theta) = R(theta) A0`` (``theta`` the error rotation vector of
:mod:`starsense.attitude.covariance`: x, y cross-boresight, z roll).

The exposure is integrated at Gauss-Legendre nodes in time (:func:`time_nodes`): one node at
mid-exposure for a star that does not move, else four per panel of two PSF sigmas of track.
The derivatives of the node positions with respect to ``theta`` and ``w`` are central
differences of the projection (steps of 1e-6 rad: the truncation error, ~eps^2 f, is below
1e-7 px at f = 10^4 px, the rounding ~1e-16 f / eps below 1e-6 px).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.errors import InputError

__all__ = ["NodePositions", "node_positions", "rotvec_matrices", "time_nodes", "track_nodes"]

#: finite-difference step of the attitude, rad
EPS_RAD = 1e-6
#: Gauss-Legendre nodes per panel of track
NODES_PER_PANEL = 4


def time_nodes(length_px: float, sigma_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the exposure's quadrature: times in [-1/2, 1/2] (of the exposure) and weights.

    Parameters
    ----------
    length_px : float
        The longest track among the stars, px.
    sigma_px : float
        The PSF's width (Gaussian sigma), px.

    Returns
    -------
    fractions, weights : ndarray, shape (K,)
        Node times as fractions of the exposure from mid-exposure; weights summing to 1.
    """
    if length_px < 0.02 * sigma_px:  # within 1e-4 px^2 of a static star's second moment
        return np.zeros(1), np.ones(1)
    panels = max(1, math.ceil(length_px / (2.0 * sigma_px)))
    t, w = np.polynomial.legendre.leggauss(NODES_PER_PANEL)
    edges = np.linspace(-0.5, 0.5, panels + 1)
    mid, half = 0.5 * (edges[1:] + edges[:-1]), 0.5 * (edges[1:] - edges[:-1])
    frac = (mid[:, None] + half[:, None] * t[None, :]).ravel()
    weights = (half[:, None] * w[None, :]).ravel()
    return frac, weights


@dataclass(frozen=True)
class NodePositions:
    """Positions of sources at the exposure's time nodes, and their derivatives.

    Attributes
    ----------
    x, y : ndarray, shape (S, K)
        Pixel positions (x = column, y = row) at each node.
    weights : ndarray, shape (K,)
        The nodes' quadrature weights (sum 1).
    dx, dy : ndarray, shape (S, K, P)
        Derivatives with respect to the P geometric parameters (theta, then w if fitted), px
        per rad (theta) or px per rad/s (w).
    """

    x: np.ndarray
    y: np.ndarray
    weights: np.ndarray
    dx: np.ndarray
    dy: np.ndarray


def rotvec_matrices(rotvec) -> np.ndarray:
    """Rotation matrices of rotation vectors (..., 3) by Rodrigues' formula, shape (..., 3, 3)."""
    r = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(r, axis=-1)[..., None, None]
    k = np.zeros((*r.shape[:-1], 3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -r[..., 2], r[..., 1], -r[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = r[..., 2], -r[..., 1], r[..., 0]
    small = angle < 1e-4  # sin(a)/a and (1 - cos a)/a^2 by their series (error < 1e-17)
    safe = np.where(small, 1.0, angle)
    s = np.where(small, 1.0 - angle**2 / 6.0, np.sin(safe) / safe)
    c = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + s * k + c * (k @ k)


@functools.lru_cache(maxsize=64)
def _steps(n_par: int, eps_w: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the central differences' perturbations and the attitude steps' matrices.

    ``(steps_t, steps_w, R(steps_t))``: (D, 3) attitude and rate steps and (D, 3, 3) matrices,
    D = 1 + 2 P (none, then + and - each parameter); read-only (shared between calls).
    """
    steps_t, steps_w = np.zeros((1 + 2 * n_par, 3)), np.zeros((1 + 2 * n_par, 3))
    for j in range(n_par):
        for k, sign in enumerate((1.0, -1.0)):
            if j < 3:
                steps_t[1 + 2 * j + k, j] = sign * EPS_RAD
            else:
                steps_w[1 + 2 * j + k, j - 3] = sign * eps_w
    for a in (steps_t, steps_w):
        a.flags.writeable = False
    mats = rotvec_matrices(steps_t)
    mats.flags.writeable = False
    return steps_t, steps_w, mats


def _camera_rotations(rotation: Rotation, rate, tau, steps) -> np.ndarray:
    """Matrices R(-(w + dw) tau) R(dtheta) A, shape (D, K, 3, 3), for D perturbations."""
    _, rate_steps, theta_mats = steps
    head = theta_mats @ rotation.as_matrix()  # (D, 3, 3)
    if not np.any(tau):  # one node at mid-exposure: no turn
        return head[:, None]
    turns = np.asarray(rate)[None, :] + rate_steps  # (D, 3)
    turn = rotvec_matrices(-turns[:, None, :] * tau[None, :, None])  # (D, K, 3, 3)
    return turn @ head[:, None]


def node_positions(
    sensor,
    vectors,
    rotation: Rotation,
    *,
    rate_rad_s,
    exposure_s: float,
    fractions,
    weights,
    fit_rate: bool = False,
) -> NodePositions:
    """Project sources at the exposure's nodes, with derivatives (module docstring).

    Parameters
    ----------
    sensor : Sensor
    vectors : ndarray, shape (S, 3)
        ICRS unit vectors of the sources.
    rotation : Rotation
        Mid-exposure attitude (ICRS to camera).
    rate_rad_s : array_like, shape (3,)
        Body rate, camera frame, rad/s.
    exposure_s : float
        Exposure, s.
    fractions, weights : ndarray, shape (K,)
        The time nodes (:func:`time_nodes`).
    fit_rate : bool
        Also differentiate with respect to the rate (P = 6, else 3).

    Returns
    -------
    NodePositions
    """
    v = np.asarray(vectors, dtype=float)
    w = np.asarray(rate_rad_s, dtype=float)
    tau = np.asarray(fractions, dtype=float) * exposure_s
    n_par = 6 if fit_rate else 3
    eps_w = EPS_RAD / max(0.5 * exposure_s, 1e-9)
    mats = _camera_rotations(rotation, w, tau, _steps(n_par, eps_w))  # (D, K, 3, 3)
    cam = np.einsum("dkij,sj->dski", mats, v)  # (D, S, K, 3)
    px, py = sensor.project(cam)
    scale = np.array([EPS_RAD] * 3 + [eps_w] * 3)[:n_par]
    dx = (px[1::2] - px[2::2]) / (2.0 * scale[:, None, None])  # (P, S, K)
    dy = (py[1::2] - py[2::2]) / (2.0 * scale[:, None, None])
    return NodePositions(
        px[0], py[0], np.asarray(weights, float), np.moveaxis(dx, 0, -1), np.moveaxis(dy, 0, -1)
    )


def track_nodes(
    sensor,
    vectors,
    rotation,
    *,
    rate_rad_s,
    sigma_px: float,
    moving: bool,
    max_nodes: float = math.inf,
):
    """Return the exposure's quadrature (fractions, weights) and the sources' nodes on it.

    Parameters
    ----------
    sensor : Sensor
    vectors : (ndarray (S, 3), ndarray (N, 3))
        The free sources (whose longest track at the rate sets the quadrature), and every
        source (whose nodes are returned), ICRS.
    rotation : Rotation
        Mid-exposure attitude, ICRS to camera.
    rate_rad_s : ndarray (3,)
        Body rate, camera frame, rad/s.
    sigma_px : float
        The PSF's width, px (:func:`time_nodes`).
    moving : bool
        Resolve the tracks (else one node at mid-exposure).
    max_nodes : float
        Refuse (InputError) more nodes over the sources than this, before laying them out:
        a track thousands of pixels long (a rate far from the frame's) needs as many nodes.

    Returns
    -------
    fractions, weights : ndarray (K,)
    nodes : the sources' positions at the nodes (:func:`node_positions`)
    """
    v_free, allv = vectors
    te = sensor.exposure_s
    ends = node_positions(
        sensor,
        v_free,
        rotation,
        rate_rad_s=rate_rad_s,
        exposure_s=te,
        fractions=np.array([-0.5, 0.5]),
        weights=np.array([0.5, 0.5]),
    )
    lengths = np.hypot(np.diff(ends.x), np.diff(ends.y)) if len(v_free) else np.zeros(1)
    if not np.isfinite(lengths).any():  # every star behind the camera (a fit's wild step)
        raise InputError("no fitted star projects onto the detector at this attitude and rate")
    length = float(np.nanmax(lengths))
    frac, wts = time_nodes(length if moving else 0.0, sigma_px)
    if len(frac) * len(allv) > max_nodes:
        raise InputError(
            f"the stars' tracks ({length:.3g} px) need {len(frac) * len(allv):.3g} nodes, more "
            f"than the {max_nodes:.3g} a fit may evaluate"
        )
    nodes = node_positions(
        sensor, allv, rotation, rate_rad_s=rate_rad_s, exposure_s=te, fractions=frac, weights=wts
    )
    return frac, wts, nodes
