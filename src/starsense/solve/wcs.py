"""World coordinate systems of solved frames: TAN, and TAN-SIP when the lens distorts.

A pinhole frame is exactly a gnomonic (TAN) projection: with the camera axes x, y in ICRS and
east, north at the boresight, the CD matrix is (180/pi) / f_px [[e.x, e.y], [n.x, n.y]] and
CRPIX the principal point. A sensor with Brown-Conrady distortion
(:mod:`starsense.geometry.distortion`) adds SIP polynomials (Shupe et al. 2005, ASP Conf. Ser.
347, 491): A, B take the measured pixel offsets ``(u, v)`` from CRPIX to the pinhole ones,
``u + A(u, v)``, and AP, BP go back. Both are least-squares fits of the exact model on a grid
over the detector, of total degree ``order``: by default the lowest odd degree (3..9) whose
largest error on the grid is below :data:`SIP_TOLERANCE_PX` (the inverse of a 10 % distortion
at the corner needs 9); that error goes into the header.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from starsense._io import atomic_path
from starsense.errors import InputError
from starsense.geometry.attitude import east_north
from starsense.geometry.distortion import distort, undistort

__all__ = ["SIP_TOLERANCE_PX", "sip_coefficients", "solution_wcs", "write_solution_wcs"]

_GRID = 41  # grid points per axis for the SIP fits
#: largest SIP fit error the automatic order aims for, px
SIP_TOLERANCE_PX = 0.01


def _monomials(u: np.ndarray, v: np.ndarray, order: int) -> tuple[np.ndarray, list]:
    """Design matrix of u^p v^q, 2 <= p + q <= order (SIP's terms), and the (p, q) list."""
    terms = [(p, q) for p in range(order + 1) for q in range(order + 1 - p) if p + q >= 2]
    return np.column_stack([u**p * v**q for p, q in terms]), terms


def _fit_poly(u, v, du, dv, order: int, scale: float):
    """Least-squares SIP matrices for offsets (du, dv) at (u, v); fitted in scaled units."""
    m, terms = _monomials(u / scale, v / scale, order)
    coeff, *_ = np.linalg.lstsq(m, np.column_stack([du, dv]), rcond=None)
    a = np.zeros((order + 1, order + 1))
    b = np.zeros((order + 1, order + 1))
    for (p, q), (ca, cb) in zip(terms, coeff, strict=True):
        a[p, q] = ca / scale ** (p + q)
        b[p, q] = cb / scale ** (p + q)
    fit = m @ coeff
    err = float(np.max(np.hypot(fit[:, 0] - du, fit[:, 1] - dv)))
    return a, b, err


def sip_coefficients(sensor, order: int = 5) -> tuple[np.ndarray, ...]:
    """Return the SIP matrices (A, B, AP, BP) of a sensor's distortion and the largest fit error.

    Parameters
    ----------
    sensor : Sensor
        Its focal length (px), principal point and Brown-Conrady coefficients.
    order : int
        Total polynomial degree, 2..9.

    Returns
    -------
    a, b, ap, bp : ndarray, shape (order + 1, order + 1)
        SIP coefficient matrices, pixel units.
    max_error_px : float
        Largest error of the forward or inverse fit on the grid, px.
    """
    det = sensor.detector
    lens = (sensor.focal_length_px, sensor.principal_point_px, sensor.optics.distortion)
    return _sip_fit(lens, (det.columns, det.rows), order)


def _sip_fit(lens, size, order: int) -> tuple[np.ndarray, ...]:
    """SIP matrices of a lens ``(f_px, (cx, cy), (k1, k2, p1, p2))`` over ``size`` (w, h)."""
    if not 2 <= int(order) <= 9:
        raise InputError(f"order must be within [2, 9], got {order!r}")
    f, (cx, cy), coeffs = lens
    xs = np.linspace(-0.5, size[0] - 0.5, _GRID) - cx
    ys = np.linspace(-0.5, size[1] - 0.5, _GRID) - cy
    u, v = (g.ravel() for g in np.meshgrid(xs, ys))  # measured (distorted) offsets, px
    xi, yi = undistort(u / f, v / f, coeffs)
    ui, vi = xi * f, yi * f  # pinhole offsets, px
    scale = float(max(abs(xs).max(), abs(ys).max()))
    a, b, err_fwd = _fit_poly(u, v, ui - u, vi - v, order, scale)
    # inverse on a grid of pinhole offsets covering the detector's image
    xd, yd = distort(ui / f, vi / f, coeffs)
    ap, bp, err_inv = _fit_poly(ui, vi, xd * f - ui, yd * f - vi, order, scale)
    return a, b, ap, bp, max(err_fwd, err_inv)


def _lens(solution):
    """Return the solved frame's lens ``(f_px, (cx, cy), coefficients)``, or None (pinhole).

    Its sensor's, or the radial lens found with nothing known (``Solution.distortion``).
    """
    sensor = solution.sensor
    if sensor is not None:
        if not sensor.optics.has_distortion:
            return None
        return sensor.focal_length_px, sensor.principal_point_px, sensor.optics.distortion
    d = solution.distortion
    if not d or not (d["k1"] or d["k2"]):
        return None
    rows, cols = solution.image_shape
    centre = ((cols - 1) / 2.0, (rows - 1) / 2.0)
    return d["focal_length_px"], centre, (d["k1"], d["k2"], 0.0, 0.0)


def _auto_sip(lens, size, order: int | None) -> tuple[int, tuple]:
    """Return the SIP order to use (lowest odd one within tolerance if None) and its fit."""
    if order is not None:
        return order, _sip_fit(lens, size, order)
    for k in (3, 5, 7, 9):
        fit = _sip_fit(lens, size, k)
        if fit[-1] <= SIP_TOLERANCE_PX:
            break
    return k, fit


def solution_wcs(solution, sip_order: int | None = None):
    """Return an astropy WCS of a solved frame: TAN, or TAN-SIP when its sensor distorts.

    Parameters
    ----------
    solution : Solution
        A solved frame (:class:`starsense.solve.solver.Solution`); its ``sensor`` gives the
        principal point and distortion, else the radial lens found with nothing known
        (``distortion``), else a pinhole at the image centre.
    sip_order : int, optional
        Degree of the SIP polynomials (default: the lowest odd one within
        :data:`SIP_TOLERANCE_PX`).

    Returns
    -------
    astropy.wcs.WCS

    Raises
    ------
    InputError
        The frame is not solved.
    """
    from astropy.wcs import WCS, Sip

    if not solution.solved:
        raise InputError(f"no WCS for an unsolved frame (status {solution.status})")
    rows, cols = solution.image_shape
    sensor = solution.sensor
    axes = solution.rotation.as_matrix()  # rows: camera x, y, z in ICRS
    east, north = east_north(solution.ra_rad, solution.dec_rad)
    cd = np.degrees(1.0 / solution.focal_px) * np.array(
        [[east @ axes[0], east @ axes[1]], [north @ axes[0], north @ axes[1]]]
    )
    if sensor is not None:
        cx, cy = sensor.principal_point_px
    else:
        cx, cy = (cols - 1) / 2.0, (rows - 1) / 2.0
    w = WCS(naxis=2)
    w.wcs.ctype = ["RA---TAN", "DEC--TAN"]
    # the boresight is the principal point: the attitude's camera z axis
    w.wcs.crval = [solution.ra_deg, solution.dec_deg]
    w.wcs.crpix = [cx + 1.0, cy + 1.0]
    w.wcs.cd = cd
    w.wcs.radesys = "ICRS"
    w.pixel_shape = (cols, rows)
    lens = _lens(solution)
    if lens is not None:
        _, (a, b, ap, bp, _) = _auto_sip(lens, (cols, rows), sip_order)
        w.wcs.ctype = ["RA---TAN-SIP", "DEC--TAN-SIP"]
        w.sip = Sip(a, b, ap, bp, w.wcs.crpix)
    return w


def write_solution_wcs(solution, path: str | Path, sip_order: int | None = None) -> Path:
    """Write a solved frame's WCS as a FITS header (no data), atomically (:mod:`starsense._io`).

    Parameters
    ----------
    solution : Solution
        A solved frame.
    path : path-like
        The FITS file to create or replace; its directory must exist.
    sip_order : int, optional
        Degree of the SIP polynomials (when the sensor distorts; default automatic).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from astropy.io import fits

    path = Path(path)
    w = solution_wcs(solution, sip_order)
    header = w.to_header(relax=True)
    header["COMMENT"] = "starsense solution: " + solution.message
    if w.sip is not None:
        rows, cols = solution.image_shape
        order, fit = _auto_sip(_lens(solution), (cols, rows), sip_order)
        header["COMMENT"] = f"SIP order {order}: largest fit error {fit[-1]:.2e} px"
    with atomic_path(path, suffix=".tmp") as tmp:
        fits.PrimaryHDU(header=header).writeto(tmp, overwrite=True)
    return path
