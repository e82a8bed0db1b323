"""The point-spread function integrated over a pixel, with its gradient: one profile per shape.

Every profile here answers one question: what fraction of a star's light falls in a pixel whose
centre lies ``(dx, dy)`` px from the star (x along the columns, y along the rows), and how fast
that fraction changes as the star moves. That pixel-integrated PSF (the "effective PSF" of
Anderson & King 2000, photutils' ``ImagePSF``) is all the forward model needs: the expected
pixels of a star are its electrons times it, summed along the star's track.

Shapes (:class:`~starsense.sensor.psf_spec.PSFSpec`), each of the FWHM of the Gaussian of sigma
``detector.psf_sigma_px``:

- **Gaussian**: exact, a product of two one-dimensional erf differences (Dzamba & Enright 2014,
  eq. 9 integrated over the pixel), and its exact gradient (differences of the normal density).
- **Moffat**: ``(beta - 1) / (pi alpha^2) (1 + r^2 / alpha^2)^-beta`` (Moffat 1969; GalSim's
  ``Moffat``), FWHM ``2 alpha sqrt(2^(1/beta) - 1)``.
- **Airy**: the diffraction pattern of a circular aperture with an optional central
  obstruction ``e``: ``pi / (4 l^2 (1 - e^2)) [2 J1(x)/x - e^2 2 J1(e x)/(e x)]^2`` with
  ``x = pi r / l``, ``l`` = lambda/D in px (Born & Wolf sec. 8.5; its integral over the plane
  is 1 by Parseval's theorem), scaled to the FWHM.
- **Empirical**: a PSF sampled on a grid of ``1 / oversampling`` px (a lab measurement, a
  Zemax export, a GalSim ``OpticalPSF`` drawn with ``method="no_pixel"``).

The last three are tabulated once per width: the profile is sampled on a fine grid (at most
1/32 px, or FWHM/24), averaged over a one-pixel box by cumulative sums (the pixel integral; the
midpoint rule's error is below 1e-5 of the peak at these steps) and kept on a grid of 1/8 px,
between whose nodes a cubic B-spline gives the value and its derivatives
(:class:`~starsense.model.psf_table.SplineTable`, fast on grids of whole pixels). The table
covers ``radius_px`` around the star, its last 2 px tapered smoothly to zero (so that a pixel's
light and its derivatives stay continuous as a star moves past the edge): light beyond (an Airy
or a Moffat wing) is neither drawn nor modelled; the fraction left out is
:attr:`PixelPSF.outside_fraction`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import erf, j1

from starsense.errors import InputError
from starsense.model.psf_table import SplineTable
from starsense.sensor.psf_spec import FWHM_PER_SIGMA, PSFSpec

__all__ = ["PixelPSF", "gaussian_pixel_1d", "pixel_psf", "psf_of"]

SQRT2 = math.sqrt(2.0)
INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)
#: table nodes per pixel (the pixel-integrated PSF is at least a pixel wide: cubic splines on
#: 1/8 px are within ~1e-5 of the peak)
TABLE_OVERSAMPLING = 8
#: the tabulated profile falls smoothly to zero over this much of its edge, px
TAPER_PX = 2.0
#: largest extent of a tabulated profile, px
MAX_RADIUS_PX = 32.0


class PixelPSF:
    """A pixel-integrated PSF of one shape and width (module docstring).

    Call :meth:`evaluate` with the offsets of pixel centres from the star.

    Attributes
    ----------
    spec : PSFSpec
        The shape.
    sigma_px : float
        The width: sigma of the Gaussian of the same FWHM, px.
    radius_px : float
        Beyond this offset (either axis) the profile is zero, px.
    outside_fraction : float
        The star's light beyond ``radius_px`` (not drawn, not modelled).
    """

    def __init__(self, spec: PSFSpec, sigma_px: float) -> None:
        if not (math.isfinite(sigma_px) and sigma_px > 0):
            raise InputError(f"PSF width must be a finite number > 0 px, got {sigma_px!r}")
        self.spec = spec
        self.sigma_px = float(sigma_px)
        self._table = None
        if spec.is_gaussian:
            self.radius_px = spec.radius_px or 6.0 * self.sigma_px
            self.outside_fraction = 0.0
            return
        density, radius = _density(spec, self.sigma_px)
        self.radius_px = min(spec.radius_px or radius, MAX_RADIUS_PX)
        self._table, inside = _table(density, self.radius_px, self.sigma_px)
        self.outside_fraction = max(0.0, 1.0 - inside)

    @property
    def fwhm_px(self) -> float:
        """Full width at half maximum of the (unintegrated) profile, px."""
        return FWHM_PER_SIGMA * self.sigma_px

    def evaluate(self, dx, dy, *, gradient: bool = True):
        """Return the fraction of the light in pixels centred ``(dx, dy)`` from the star.

        Parameters
        ----------
        dx, dy : array_like (broadcast together)
            Pixel centre minus star position, px (x = column, y = row).
        gradient : bool
            Also return the derivatives with respect to ``dx`` and ``dy`` (the negatives of
            those with respect to the star's x and y).

        Returns
        -------
        value : ndarray
            Fraction of the star's light, per pixel.
        d_dx, d_dy : ndarray
            Its derivatives, px^-1 (only with ``gradient``).
        """
        dx, dy = np.broadcast_arrays(np.asarray(dx, float), np.asarray(dy, float))
        if self._table is None:
            return _gaussian(dx, dy, self.sigma_px, gradient)
        return self._table.points(dx, dy, gradient=gradient)

    def grid(self, x0, y0, shape: tuple[int, int], *, gradient: bool = True):
        """:meth:`evaluate` on grids of whole pixels: offsets ``x0 + j`` and ``y0 + i``.

        Parameters
        ----------
        x0, y0 : array_like, shape (N,)
            Each grid's first column's and first row's offset from its star, px.
        shape : (int, int)
            Rows and columns of every grid.

        Returns
        -------
        value : ndarray, shape (N, rows, columns)
        d_dx, d_dy : ndarray, shape (N, rows, columns)
            Only with ``gradient``.
        """
        x0 = np.asarray(x0, dtype=float).ravel()
        y0 = np.asarray(y0, dtype=float).ravel()
        if self._table is not None:
            return self._table.grid(x0, y0, shape, gradient=gradient)
        px, dpx = gaussian_pixel_1d(x0[:, None] + np.arange(shape[1]), self.sigma_px)
        py, dpy = gaussian_pixel_1d(y0[:, None] + np.arange(shape[0]), self.sigma_px)
        v = py[:, :, None] * px[:, None, :]
        if not gradient:
            return v
        return v, py[:, :, None] * dpx[:, None, :], dpy[:, :, None] * px[:, None, :]


def gaussian_pixel_1d(d, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Fraction of a 1-D Gaussian in unit pixels centred ``d`` from it, and its d/dd.

    ``1/2 [erf((d + 1/2) / (sqrt2 s)) - erf((d - 1/2) / (sqrt2 s))]`` and
    ``[phi((d + 1/2) / s) - phi((d - 1/2) / s)] / s`` (phi the normal density).
    """
    a, b = (d + 0.5) / sigma, (d - 0.5) / sigma
    p = 0.5 * (erf(a / SQRT2) - erf(b / SQRT2))
    dp = (np.exp(-0.5 * a * a) - np.exp(-0.5 * b * b)) * INV_SQRT2PI / sigma
    return p, dp


def _gaussian(dx, dy, sigma, gradient):
    """Return the exact pixel integral of a Gaussian and its gradient (separable)."""
    px, dpx = gaussian_pixel_1d(dx, sigma)
    py, dpy = gaussian_pixel_1d(dy, sigma)
    if not gradient:
        return px * py
    return px * py, dpx * py, px * dpy


def _density(spec: PSFSpec, sigma: float):
    """Return the profile's density ``f(x, y)`` (per px^2) and its default radius, px."""
    fwhm = FWHM_PER_SIGMA * sigma
    if spec.kind == "moffat":
        beta = spec.moffat_beta
        alpha = fwhm / (2.0 * math.sqrt(2.0 ** (1.0 / beta) - 1.0))
        norm = (beta - 1.0) / (math.pi * alpha * alpha)
        # light outside radius R: (1 + R^2 / alpha^2)^(1 - beta); R for 1e-3 of it
        r999 = alpha * math.sqrt(1e-3 ** (1.0 / (1.0 - beta)) - 1.0)

        def moffat(x, y):
            return norm * (1.0 + (x * x + y * y) / (alpha * alpha)) ** (-beta)

        return moffat, min(max(4.0 * fwhm, r999), 8.0 * fwhm)
    if spec.kind == "airy":
        e = spec.airy_obscuration
        lam = fwhm * math.pi / (2.0 * _airy_half_width(e))  # lambda/D in px
        norm = math.pi * (1.0 - e * e) / (4.0 * lam * lam)  # the amplitude is 1 at 0

        def airy(x, y):
            u = math.pi * np.hypot(x, y) / lam
            return norm * _airy_amplitude(u, e) ** 2

        return airy, 8.0 * fwhm
    from scipy.interpolate import RectBivariateSpline

    samples, os_ = spec.samples, spec.oversampling
    half = (np.array(samples.shape[::-1]) - 1) / 2.0 / os_  # x, y half-extent, px
    spline = RectBivariateSpline(
        (np.arange(samples.shape[0]) - (samples.shape[0] - 1) / 2.0) / os_,
        (np.arange(samples.shape[1]) - (samples.shape[1] - 1) / 2.0) / os_,
        samples * os_ * os_,  # per px^2
        kx=3,
        ky=3,
    )

    def empirical(x, y):
        out = spline.ev(y, x)
        out[(np.abs(x) > half[0]) | (np.abs(y) > half[1])] = 0.0
        return np.clip(out, 0.0, None)

    return empirical, float(min(half))


def _airy_amplitude(u, e):
    """``2 J1(u)/u - e^2 2 J1(e u)/(e u)``, normalised to 1 at u = 0."""
    u = np.asarray(u, dtype=float)
    safe = np.where(u == 0.0, 1.0, u)
    a = np.where(u == 0.0, 1.0, 2.0 * j1(safe) / safe)
    if e > 0.0:
        eu = e * safe
        a = a - e * e * np.where(u == 0.0, 1.0, 2.0 * j1(eu) / eu)
    return a / (1.0 - e * e)


@functools.lru_cache(maxsize=32)
def _airy_half_width(e: float) -> float:
    """Return the ``u`` at which the Airy intensity falls to half its peak."""
    from scipy.optimize import brentq

    return brentq(lambda u: float(_airy_amplitude(u, e)) ** 2 - 0.5, 1e-6, 3.0)


def _table(density, radius: float, sigma: float):
    """Tabulate the pixel integral of ``density`` on 1/8 px out to ``radius``; its spline."""
    os_ = TABLE_OVERSAMPLING
    fine = max(4, math.ceil(1.0 / (os_ * min(1.0 / 32.0, FWHM_PER_SIGMA * sigma / 24.0))))
    step = 1.0 / (os_ * fine)  # fine samples per px: os_ * fine
    n_nodes = round(2.0 * radius * os_) + 1
    radius = (n_nodes - 1) / (2.0 * os_)
    per_px = os_ * fine
    m = (n_nodes - 1) * fine + per_px  # fine cells spanning [-radius - 0.5, radius + 0.5]
    g = -radius - 0.5 + (np.arange(m) + 0.5) * step
    if m * m > 3e7:  # bounded memory (~240 MB): a wide, sharp profile
        raise InputError(
            f"PSF table of {m} x {m} fine samples (radius {radius:g} px, width {sigma:g} px) is "
            "too large: set psf.radius_px smaller"
        )
    f = density(g[None, :], g[:, None]) * (step * step)
    c = np.zeros((m + 1, m + 1))
    np.cumsum(np.cumsum(f, axis=0), axis=1, out=c[1:, 1:])
    lo = np.arange(n_nodes) * fine
    hi = lo + per_px
    box = c[np.ix_(hi, hi)] - c[np.ix_(lo, hi)] - c[np.ix_(hi, lo)] + c[np.ix_(lo, lo)]
    nodes = np.linspace(-radius, radius, n_nodes)
    # a smooth edge: the table falls to zero over its last TAPER_PX (cos^2), so that the
    # model's pixels and their derivatives stay continuous as a star's offset crosses it
    ramp = np.clip((radius - np.abs(nodes)) / TAPER_PX, 0.0, 1.0)
    taper = np.sin(0.5 * math.pi * ramp) ** 2
    box *= taper[:, None] * taper[None, :]
    inside = float(box.sum()) / (os_ * os_)  # the integral over all offsets: the light drawn
    return SplineTable(box, radius, os_), inside


@functools.lru_cache(maxsize=64)
def _cached(spec: PSFSpec, sigma_q: float, samples_id: int) -> PixelPSF:
    del samples_id  # part of the key only: empirical specs differ by their samples
    return PixelPSF(spec, sigma_q)


def pixel_psf(spec: PSFSpec, sigma_px: float) -> PixelPSF:
    """Return the (cached) :class:`PixelPSF` of a shape at a width.

    Widths of tabulated profiles are taken to 1e-3 relative (a field-varying width reuses
    tables); a Gaussian's is exact.
    """
    if spec.is_gaussian:  # exact and free to build: no table to reuse
        return PixelPSF(spec, float(sigma_px))
    q = float(f"{float(sigma_px):.4g}")
    return _cached(spec, q, id(spec.samples) if spec.samples is not None else 0)


def psf_of(sensor, sigma_px: float | None = None) -> PixelPSF:
    """Return the sensor's pixel-integrated PSF at its width (or ``sigma_px``)."""
    s = sensor.detector.psf_sigma_px if sigma_px is None else sigma_px
    return pixel_psf(sensor.psf, s)
