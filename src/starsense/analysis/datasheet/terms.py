"""Error terms beside the temporal noise (ECSS-E-ST-60-20C names), measured or modelled.

* **Pixel spatial error**: the centroider's deterministic error against the star's sub-pixel
  position, measured by running the tracker's own detector on noiseless renders
  (:func:`starsense.render.psf.gaussian_stamp`) over a grid of sub-pixel positions.
* **Detector non-uniformity (PRNU)**: a pixel gain spread ``p`` moves a centre-of-mass
  centroid by ``p sqrt(sum f_k^2 (x_k - x_c)^2) / sum f_k`` (rms per axis), ``f_k`` the star's
  light in pixel k: independent of the star's brightness, ``0.20 p`` px for a well-sampled
  Gaussian (``1 / sqrt(8 pi)``), more for an undersampled one; computed here on the
  pixel-integrated PSF over sub-pixel phases.
* **Confusion**: catalogue stars fainter than a star, inside its centroid window, pull its
  centre of gravity towards them: a neighbour of ``f`` electrons at offset ``x`` (px) moves a
  star of ``F`` by ``w f x / (F + w f)`` (``w`` the part of the neighbour's light inside the
  window). Over the sky such neighbours fall at random (the catalogue's star counts per
  magnitude, a Poisson density ``rho`` per square pixel), so the shift's variance per axis is
  ``sum_b rho_b integral (w f_b x / (F + B + w f_b))^2 dA`` (:func:`confusion_px`; ``B`` the
  mean light all the neighbours put in the window, which dilutes each one's pull); stars brighter
  than the star are left out (they are detected as themselves, and a blend is the solver's).
* **Stellar aberration, if uncorrected**: the apparent displacement of every star by the
  observer's velocity (first order: ``v/c sin(angle to the apex)``), fitted as a rotation over
  the field: the common part is a cross-boresight error, the differential part is left over.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.special import ndtr

from starsense.detect.threshold import StarDetector
from starsense.render.psf import gaussian_stamp

__all__ = [
    "EARTH_ORBITAL_SPEED_M_S",
    "SPEED_OF_LIGHT_M_S",
    "PixelSpatialError",
    "aberration_error",
    "confusion_px",
    "pixel_spatial_error",
    "prnu_centroid_px",
]

#: speed of light, m/s (exact, SI)
SPEED_OF_LIGHT_M_S = 299_792_458.0
#: Earth's mean orbital speed, m/s: 2 pi AU / sidereal year (29.78 km/s), whose ratio to c is
#: the constant of annual aberration, 20.4955 arcsec (IAU 1976)
EARTH_ORBITAL_SPEED_M_S = 2.0 * math.pi * 149_597_870_700.0 / (365.256363004 * 86_400.0)


@dataclass(frozen=True)
class PixelSpatialError:
    """The centroider's bias against sub-pixel position, per star brightness (pixels).

    Attributes
    ----------
    electrons : ndarray (K,)
        Photo-electrons of the rendered stars.
    rms_px, max_px : ndarray (K,)
        Rms and largest bias over the sub-pixel grid (both axes pooled).
    n_positions : int
        Sub-pixel positions per star brightness.
    """

    electrons: np.ndarray
    rms_px: np.ndarray
    max_px: np.ndarray
    n_positions: int

    def rms(self, electrons) -> np.ndarray:
        """Return the rms bias (px) of stars of ``electrons`` (log-log interpolation)."""
        ok = np.isfinite(self.rms_px)
        e = np.asarray(electrons, dtype=float)
        if not ok.any():
            return np.full(e.shape, np.nan)
        grid, r = self.electrons[ok], np.maximum(self.rms_px[ok], 1e-6)
        e = np.clip(e, grid[0], grid[-1])  # held at the ends of the measured range
        return np.exp(np.interp(np.log(e), np.log(grid), np.log(r)))


def pixel_spatial_error(sensor, electrons, n_side: int = 8) -> PixelSpatialError:
    """Measure the centroider's sub-pixel bias on noiseless renders of the sensor's PSF.

    Parameters
    ----------
    sensor : Sensor
        PSF, gain, bias and detection logic (the detector used by the solver).
    electrons : array_like (K,)
        Star brightnesses to measure, photo-electrons (sorted ascending on return).
    n_side : int
        Sub-pixel positions per axis (``n_side^2`` per brightness).

    Returns
    -------
    PixelSpatialError
        Brightnesses that light too few pixels to be detected get NaN.
    """
    det = sensor.detector
    detector = StarDetector.for_sensor(sensor)
    e_sorted = np.sort(np.asarray(electrons, dtype=float))
    offsets = (np.arange(n_side) + 0.5) / n_side
    rms, worst = [], []
    for n_e in e_sorted:
        reach = det.psf_sigma_px * math.sqrt(2.0 * math.log(max(n_e * det.gain_counts_per_e, 2.0)))
        half = math.ceil(reach + 4.0 * det.psf_sigma_px) + 4
        size = 2 * half + 1
        # the stamps side by side in one strip, margin + 1 columns of bias between them: with
        # the detector's constant background each stamp is detected as if alone
        xy = [(half + dx - 0.5, half + dy - 0.5) for dx in offsets for dy in offsets]
        pitch = size + detector.margin_px + 1
        strip = np.full((size, pitch * len(xy)), float(det.bias_counts))
        for k, (x, y) in enumerate(xy):
            stamp, _, _ = gaussian_stamp(
                x, y, sigma_px=det.psf_sigma_px, electrons=n_e, box=(0, size, 0, size)
            )
            # as the renderer reads a pixel: the well clips the charge, the ADC the counts with
            # the bias in them (a pixel's signal tops out at the ADC's top less the bias)
            signal = np.minimum(stamp, det.full_well_e) * det.gain_counts_per_e
            counts = np.minimum(signal + det.bias_counts, det.saturation_counts)
            strip[:, k * pitch : k * pitch + size] = counts
        found = detector(strip)
        which = (found.x // pitch).astype(int)
        first = np.unique(which, return_index=True)[1]  # brightest of each stamp
        ok = len(first) == len(xy)
        e = np.concatenate(
            [
                found.x[first] - which[first] * pitch - [xy[k][0] for k in which[first]],
                found.y[first] - [xy[k][1] for k in which[first]],
            ]
        )
        rms.append(math.sqrt(np.mean(e**2)) if ok else math.nan)
        worst.append(float(np.max(np.abs(e))) if ok else math.nan)
    return PixelSpatialError(e_sorted, np.array(rms), np.array(worst), n_side * n_side)


def aberration_error(sensor, speed_m_s: float, n_side: int = 9) -> tuple[float, float]:
    """Return the worst attitude error (cross, roll; rad) of uncorrected stellar aberration.

    Stars on an ``n_side`` x ``n_side`` grid over the detector are displaced by the observer's
    velocity (first order, ``v/c (a - (a.r) r)`` for apex direction ``a``); the rotation that
    best maps the true directions onto the displaced ones (Wahba, equal weights) is the error.
    The apex is swept over directions; the largest cross-boresight and roll are returned.

    Parameters
    ----------
    sensor : Sensor
        The field (pinhole geometry).
    speed_m_s : float
        Observer speed, m/s (>= 0).
    n_side : int
        Grid points per detector axis.
    """
    det = sensor.detector
    xs = np.linspace(0.0, det.columns - 1.0, n_side)
    ys = np.linspace(0.0, det.rows - 1.0, n_side)
    gx, gy = np.meshgrid(xs, ys)
    r = sensor.unproject(gx.ravel(), gy.ravel())
    beta = float(speed_m_s) / SPEED_OF_LIGHT_M_S
    cross = roll = 0.0
    for theta in np.linspace(0.0, math.pi, 7):
        for phi in np.linspace(0.0, math.pi, 5):
            apex = np.array(
                [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
            )
            moved = r + beta * (apex - (r @ apex)[:, None] * r)
            moved /= np.linalg.norm(moved, axis=1)[:, None]
            rot, _ = Rotation.align_vectors(moved, r)
            v = rot.as_rotvec()
            cross = max(cross, float(math.hypot(v[0], v[1])))
            roll = max(roll, float(abs(v[2])))
    return cross, roll


def prnu_centroid_px(sensor, n_side: int = 8) -> float:
    """Return the centroid shift (px rms per axis) the detector's PRNU gives a star.

    ``p sqrt(<sum f_k^2 (x_k - x_c)^2>) / sum f_k`` over ``n_side^2`` sub-pixel phases of the
    pixel-integrated Gaussian PSF (a centre-of-mass centroid; the module docstring).

    Parameters
    ----------
    sensor : Sensor
        PSF sigma and ``detector.prnu_fraction``.
    n_side : int
        Sub-pixel phases per axis.

    Returns
    -------
    float
        px; 0 without PRNU.
    """
    det = sensor.detector
    if det.prnu_fraction <= 0:
        return 0.0
    return det.prnu_fraction * _prnu_lever(float(det.psf_sigma_px), n_side)


@functools.lru_cache(maxsize=64)
def _prnu_lever(sigma_px: float, n_side: int) -> float:
    """sqrt(<sum f_k^2 (x_k - x_c)^2>) / sum f_k of a unit Gaussian, averaged over phases."""
    half = math.ceil(6.0 * sigma_px) + 2
    size = 2 * half + 1
    offsets = (np.arange(n_side) + 0.5) / n_side
    acc = []
    for dx in offsets:
        for dy in offsets:
            x, y = half + dx - 0.5, half + dy - 0.5
            f, _, _ = gaussian_stamp(x, y, sigma_px=sigma_px, electrons=1.0, box=(0, size, 0, size))
            total = f.sum()
            cols = np.arange(size)[None, :]
            xc = (f * cols).sum() / total
            acc.append((f**2 * (cols - xc) ** 2).sum() / total**2)
    return math.sqrt(float(np.mean(acc)))


def confusion_px(
    electrons, window_px, *, sigma_px: float, neighbours, density_px2, reject_px=None
) -> np.ndarray:
    """Return the centroid error (px rms per axis) faint neighbours give stars (module docstring).

    Parameters
    ----------
    electrons : array_like (K,)
        The stars' photo-electrons.
    window_px : array_like (K,)
        Side of each star's centroid window, px.
    sigma_px : float
        PSF sigma, px.
    neighbours : array_like (B,)
        Photo-electrons of the neighbour classes (magnitude bins of the catalogue).
    density_px2 : array_like (B,)
        Their mean density on the sky, stars per square pixel.
    reject_px : array_like (K,), optional
        The pull (px, in angle) past which the solver's robust fit drops the star instead
        (:data:`starsense.attitude.robust.OUTLIER_SIGMA` of its sigma): such pulls are left
        out. None keeps every pull.

    Returns
    -------
    ndarray (K,)
        px; 0 where no fainter neighbour can fall.
    """
    e = np.atleast_1d(np.asarray(electrons, dtype=float))
    side = np.broadcast_to(np.asarray(window_px, dtype=float), e.shape)
    f_nb = np.asarray(neighbours, dtype=float)
    rho = np.asarray(density_px2, dtype=float)
    limit = np.broadcast_to(np.inf if reject_px is None else np.asarray(reject_px, float), e.shape)
    out = np.zeros(e.shape)
    for k, (big, s) in enumerate(zip(e, side, strict=True)):
        fainter = (f_nb < big) & (rho > 0)
        if not np.isfinite(s) or not fainter.any():
            continue
        h = 0.5 * s
        reach = h + 4.0 * sigma_px
        step = min(0.25, 0.5 * sigma_px)
        x = np.arange(-reach, reach + step, step)
        # part of a neighbour's light inside the window, per axis: its PSF over [-h, h]
        frac = ndtr((h - x) / sigma_px) - ndtr((-h - x) / sigma_px)
        # where that light lies: the centroid of its PSF cut to [-h, h] (inside of x when the
        # neighbour straddles the window's edge)
        gauss = np.exp(-0.5 * ((-h - x) / sigma_px) ** 2) - np.exp(-0.5 * ((h - x) / sigma_px) ** 2)
        xc = x + sigma_px / math.sqrt(2.0 * math.pi) * gauss / np.maximum(frac, 1e-300)
        w = frac[:, None] * frac[None, :]  # (y, x)
        area = float(np.sum(w)) * step * step
        # the mean light the other neighbours put in the window: it dilutes each one's pull
        others = float(np.sum(rho[fainter] * f_nb[fainter])) * area
        radius = np.hypot(xc[None, :], xc[:, None])
        acc = 0.0
        for f, r in zip(f_nb[fainter], rho[fainter], strict=True):
            pull = w * f / (big + others + w * f)
            kept = pull * radius <= limit[k]  # a larger pull drops the star from the fit
            acc += r * float(np.sum(np.where(kept, (pull * xc[None, :]) ** 2, 0.0))) * step * step
        out[k] = math.sqrt(acc)
    return out
