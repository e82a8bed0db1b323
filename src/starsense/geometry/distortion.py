"""Brown-Conrady lens distortion on the tangent plane: the one copy of the model.

Ideal (pinhole) tangent-plane coordinates ``(x, y)`` (tan of the off-axis angle along the
camera axes, i.e. units of the focal length) are moved to the distorted ``(x_d, y_d)`` by the
radial terms k1, k2 and the decentring (tangential) terms p1, p2 (Brown 1966, Photogrammetric
Engineering 32, 444; Conrady 1919; the convention of OpenCV's ``projectPoints``)::

    r^2 = x^2 + y^2
    x_d = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y

The inverse has no closed form; :func:`undistort` solves it by Newton's method with the
analytic 2x2 Jacobian, vectorised over points (to 1e-15 in a few iterations for distortions of
tens of percent at the field edge).
"""

from __future__ import annotations

import numpy as np

__all__ = ["NO_DISTORTION", "distort", "distortion_jacobian", "undistort"]

#: ``(k1, k2, p1, p2)`` of a distortion-free lens
NO_DISTORTION = (0.0, 0.0, 0.0, 0.0)


def distort(x, y, coefficients=NO_DISTORTION) -> tuple[np.ndarray, np.ndarray]:
    """Return distorted tangent-plane coordinates (module equations).

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Ideal tangent-plane coordinates, units of the focal length.
    coefficients : sequence of 4 floats
        ``(k1, k2, p1, p2)``: the radial coefficients (per r^2 and r^4, r in units of the focal
        length) and the decentring coefficients (``Optics.distortion``).

    Returns
    -------
    x_d, y_d : ndarray, shape (N,)
    """
    k1, k2, p1, p2 = coefficients
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    r2 = x * x + y * y
    radial = 1.0 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd


def distortion_jacobian(x, y, coefficients=NO_DISTORTION) -> np.ndarray:
    """Return d(x_d, y_d) / d(x, y), shape (N, 2, 2), of :func:`distort`.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Ideal tangent-plane coordinates.
    coefficients : sequence of 4 floats
        ``(k1, k2, p1, p2)``, as in :func:`distort`.

    Returns
    -------
    ndarray, shape (N, 2, 2)
        ``[[dxd/dx, dxd/dy], [dyd/dx, dyd/dy]]`` per point.
    """
    k1, k2, p1, p2 = coefficients
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    r2 = x * x + y * y
    radial = 1.0 + k1 * r2 + k2 * r2 * r2
    d_radial = 2.0 * k1 + 4.0 * k2 * r2  # d(radial)/d(r^2) times 2
    j = np.empty((*x.shape, 2, 2))
    j[..., 0, 0] = radial + x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x
    j[..., 0, 1] = x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
    j[..., 1, 0] = x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
    j[..., 1, 1] = radial + y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x
    return j


def undistort(
    xd, yd, coefficients=NO_DISTORTION, *, iterations: int = 20
) -> tuple[np.ndarray, np.ndarray]:
    """Return the ideal coordinates whose :func:`distort` image is ``(xd, yd)`` (Newton).

    Parameters
    ----------
    xd, yd : array_like, shape (N,)
        Distorted tangent-plane coordinates, units of the focal length.
    coefficients : sequence of 4 floats
        ``(k1, k2, p1, p2)``, as in :func:`distort`.
    iterations : int
        Largest number of Newton steps (it stops when the steps fall below 1e-15).

    Returns
    -------
    x, y : ndarray, shape (N,)
        NaN where the model cannot be inverted on its unfolded part (beyond a fold of the
        distortion, far outside a physical field: a preimage there is on the fold's other side).
    """
    k1, k2, p1, p2 = coefficients
    xd = np.asarray(xd, dtype=float)
    yd = np.asarray(yd, dtype=float)
    if not (k1 or k2 or p1 or p2):
        return xd.copy(), yd.copy()
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        fx, fy = distort(x, y, coefficients)
        rx, ry = fx - xd, fy - yd
        j = distortion_jacobian(x, y, coefficients)
        det = j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            dx = (j[..., 1, 1] * rx - j[..., 0, 1] * ry) / det
            dy = (-j[..., 1, 0] * rx + j[..., 0, 0] * ry) / det
        x, y = x - dx, y - dy
        step = np.nanmax(np.abs(np.concatenate([np.ravel(dx), np.ravel(dy)])), initial=0.0)
        if step < 1e-15:
            break
    fx, fy = distort(x, y, coefficients)
    j = distortion_jacobian(x, y, coefficients)
    det = j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0]
    trace = j[..., 0, 0] + j[..., 1, 1]
    # a preimage past a fold is not the lens's (distort maps it there, the lens never does):
    # where a barrel turns back the radial derivative is negative (det < 0), and further out,
    # the point flipped through the centre, both it and the radial factor are (det > 0, trace
    # < 0); on the lens's own part both are positive (det > 0 and trace > 0)
    bad = ~((np.hypot(fx - xd, fy - yd) < 1e-9) & (det > 0) & (trace > 0))
    if np.any(bad):
        x, y = np.where(bad, np.nan, x), np.where(bad, np.nan, y)
    return x, y
