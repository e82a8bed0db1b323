"""The least-squares fit of one frame's camera: attitude, focal length and radial distortion.

The model (:mod:`starsense.solve.radial`) places a catalogue direction ``v`` at

``p(v) = c + f D(g(R v))``

with ``R`` the attitude, ``g`` the gnomonic projection, ``D`` the radial Brown-Conrady
distortion (``(x, y) (1 + k1 r^2 + k2 r^4)``), ``f`` the focal length in pixels and ``c`` the
image centre. Its derivatives are analytic: a small rotation ``d`` turns ``R v = q`` into
``q + d x q`` (``dq/dd = -[q]x``); ``d(x, y)/dq = [[1, 0, -x], [0, 1, -y]] / q_z``;
``dD/d(x, y) = s I + (2 k1 + 4 k2 r^2) (x, y)^T (x, y)`` with ``s = 1 + k1 r^2 + k2 r^4``;
``dp/df = D``, ``dp/dk1 = f (x, y) r^2``, ``dp/dk2 = f (x, y) r^4``.

The fit is Levenberg-Marquardt with Marquardt's scaling (the damping proportional to the
diagonal of the normal matrix, so the step does not depend on the parameters' units), the
rotation updated on the left (``R <- exp(d) R``) and stored as the rotation vector of
``R R0^-1``. While the pairs may still be wrong the cost is the soft-L1 loss of each residual
component, ``2 s^2 (sqrt(1 + (e/s)^2) - 1)``, with the loss's own curvature in the normal matrix
(:func:`_weights`). The returned Jacobian's rotation columns
are derivatives about the fitted attitude: the covariance of the other parameters and the hat
matrix do not depend on how the rotation is parametrised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["LensFitResult", "RadialModel"]

#: iterations of one fit; a converged fit stops after a few
MAX_ITERATIONS = 60
#: relative decrease of the cost under which the fit has converged
COST_TOLERANCE = 1e-10
#: step, relative to the parameters' size (radians for the rotation), under which it has converged
STEP_TOLERANCE = 1e-10


@dataclass(frozen=True)
class LensFitResult:
    """The fit's parameters, residuals and Jacobian.

    Attributes
    ----------
    x : ndarray, shape (P,)
        Rotation vector of the attitude change (3), focal length (px), then the fitted radial
        terms.
    fun : ndarray, shape (2M,)
        Residuals, detection minus model, x and y of each pair in turn, px.
    jac : ndarray, shape (2M, P)
        d fun / d parameters at ``x`` (the rotation columns about the fitted attitude).
    """

    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray


class RadialModel:
    """Residuals of detections against projected catalogue stars for one set of pairs.

    Parameters
    ----------
    xy : ndarray, shape (N, 2)
        Detections, px.
    centre : ndarray, shape (2,)
        Image centre, px.
    rotation : Rotation
        The attitude the rotation vector is counted from (ICRS -> camera).
    n_terms : int
        Radial terms fitted (0-2).
    fixed : (float, float)
        The radial terms held where not fitted.
    """

    def __init__(self, xy, centre, rotation, *, n_terms: int, fixed=(0.0, 0.0)):
        self.xy, self.centre, self.r0, self.n_terms = xy, centre, rotation, n_terms
        self.fixed = fixed

    def _terms(self, theta) -> tuple[float, float]:
        k = (*theta[4 : 4 + self.n_terms], *self.fixed[self.n_terms :])
        return float(k[0]), float(k[1])

    def project(self, theta, v) -> np.ndarray:
        """Return the pixel places of directions ``v`` (N, 3); NaN behind the camera."""
        matrix = (Rotation.from_rotvec(theta[:3]) * self.r0).as_matrix()
        out, _ = self._place(matrix, theta, np.asarray(v, dtype=float), jacobian=False)
        return out

    def _place(self, matrix, theta, v, *, jacobian: bool):
        q = v @ matrix.T
        with np.errstate(divide="ignore", invalid="ignore"):
            iz = 1.0 / q[:, 2]
            x, y = q[:, 0] * iz, q[:, 1] * iz
        k1, k2 = self._terms(theta)
        r2 = x * x + y * y
        s = 1.0 + k1 * r2 + k2 * r2 * r2
        f = theta[3]
        out = np.column_stack([x * s, y * s]) * f + self.centre
        out[~(q[:, 2] > 0)] = np.nan
        if not jacobian:
            return out, None
        n = len(v)
        jac = np.empty((n, 2, 4 + self.n_terms))
        # d(x, y)/dq composed with dq/dd = -[q]x
        gx = np.column_stack([-x * q[:, 1], q[:, 2] + x * q[:, 0], -q[:, 1]]) * iz[:, None]
        gy = np.column_stack([-q[:, 2] - y * q[:, 1], y * q[:, 0], q[:, 0]]) * iz[:, None]
        a = 2.0 * k1 + 4.0 * k2 * r2
        dxx, dxy, dyy = s + a * x * x, a * x * y, s + a * y * y
        jac[:, 0, :3] = f * (dxx[:, None] * gx + dxy[:, None] * gy)
        jac[:, 1, :3] = f * (dxy[:, None] * gx + dyy[:, None] * gy)
        jac[:, 0, 3], jac[:, 1, 3] = x * s, y * s
        power = r2.copy()
        for term in range(self.n_terms):
            jac[:, 0, 4 + term], jac[:, 1, 4 + term] = f * x * power, f * y * power
            power = power * r2
        return out, jac

    def fit(self, theta0, det, v, *, scale_px=None) -> LensFitResult:
        """Least squares; robust (soft L1 beyond ``scale_px``) while pairs may be wrong."""
        xy = self.xy[det].ravel()
        v = np.asarray(v, dtype=float)
        theta = np.array(theta0, dtype=float)
        start = self.r0.as_matrix()
        matrix = Rotation.from_rotvec(theta[:3]).as_matrix() @ start
        out, jac = self._place(matrix, theta, v, jacobian=True)
        e = xy - out.ravel()
        cost = _cost(e, scale_px)
        damping = 1e-3
        for _ in range(MAX_ITERATIONS if np.isfinite(cost) else 0):
            j = jac.reshape(len(e), -1)
            gradient_w, hessian_w = _weights(e, scale_px)
            a = j.T @ (j * hessian_w[:, None])
            g = j.T @ (gradient_w * e)
            diag = np.maximum(np.diag(a), 1e-12 * max(np.max(np.diag(a)), 1e-300))
            new_cost = np.inf
            for _ in range(12):  # raise the damping until the cost falls
                step = _solve(a + damping * np.diag(diag), g)
                if step @ g - 0.5 * step @ a @ step <= COST_TOLERANCE * cost:
                    break  # the step cannot lower the cost measurably: converged
                new_matrix = _small_rotation(step[:3]) @ matrix
                new_theta = theta.copy()
                new_theta[3:] += step[3:]
                new_out, new_jac = self._place(new_matrix, new_theta, v, jacobian=True)
                new_e = xy - new_out.ravel()
                new_cost = _cost(new_e, scale_px)
                if new_cost <= cost:
                    break
                damping *= 4.0
            if not new_cost <= cost:
                break  # no step lowers the cost: at the minimum to rounding
            done = cost - new_cost <= COST_TOLERANCE * cost or _small(step, theta)
            matrix, theta, e, jac, cost = new_matrix, new_theta, new_e, new_jac, new_cost
            damping = max(damping / 3.0, 1e-9)
            if done:
                break
        theta[:3] = Rotation.from_matrix(matrix @ start.T).as_rotvec()
        return LensFitResult(x=theta, fun=e, jac=-jac.reshape(len(e), -1))


def _small_rotation(r: np.ndarray) -> np.ndarray:
    """Return the rotation matrix of rotation vector ``r`` (Rodrigues)."""
    angle = float(np.sqrt(r @ r))
    k = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    if angle < 1e-4:  # sin(a)/a and (1 - cos a)/a^2 by their series (error < 1e-17)
        s, c = 1.0 - angle**2 / 6.0, 0.5 - angle**2 / 24.0
    else:
        s, c = np.sin(angle) / angle, (1.0 - np.cos(angle)) / angle**2
    return np.eye(3) + s * k + c * (k @ k)


def _weights(e: np.ndarray, scale_px) -> tuple[np.ndarray, np.ndarray]:
    """Weights of the gradient and of the Gauss-Newton Hessian of the cost, per component.

    For the soft-L1 loss ``rho(z) = 2 (sqrt(1 + z) - 1)``, ``z = (e/s)^2``: the gradient weighs
    a residual by ``rho'(z) = (1 + z)^-1/2`` and the Hessian by ``rho' + 2 rho'' z =
    (1 + z)^-3/2`` (the loss's own curvature, as in scipy's ``least_squares``).
    """
    if scale_px is None:
        ones = np.ones_like(e)
        return ones, ones
    t = 1.0 / (1.0 + (e / scale_px) ** 2)
    root = np.sqrt(t)
    return root, t * root


def _cost(e: np.ndarray, scale_px) -> float:
    """Return the cost of residuals ``e``; infinite where a star falls behind the camera."""
    if scale_px is None:
        cost = 0.5 * float(e @ e)
    else:
        cost = float(scale_px**2 * np.sum(np.sqrt(1.0 + (e / scale_px) ** 2) - 1.0))
    return cost if np.isfinite(cost) else np.inf


def _solve(a: np.ndarray, g: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(a, g)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(a, g, rcond=None)[0]


def _small(step: np.ndarray, theta: np.ndarray) -> bool:
    size = np.abs(theta).copy()
    size[:3] = 1.0  # radians
    return bool(np.all(np.abs(step) <= STEP_TOLERANCE * np.maximum(size, 1e-3)))
