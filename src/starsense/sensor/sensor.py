"""A star sensor: optics, detector, exposure and detection thresholds, with its pixel geometry.

A :class:`Sensor` is immutable and validated on construction: a bad value raises
:class:`~starsense.errors.InputError` naming the field, the value and the allowed range (and the
file, when loaded from TOML by :mod:`starsense.sensor.load`).

Pixel convention (shared with rendering and detection): pixel centres are at integer
coordinates; pixel (row r, column c) covers x in [c - 0.5, c + 0.5), y in [r - 0.5, r + 0.5).
The principal point falls on the centre of the detector,
((columns - 1) / 2, (rows - 1) / 2), plus the optics' principal-point offset (zero unless
calibrated). Camera frame: +z boresight, +x increasing column,
+y increasing row (see :mod:`starsense.geometry.attitude`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from starsense._validate import check_scalar
from starsense.errors import InputError
from starsense.geometry.distortion import distort, distortion_jacobian, undistort
from starsense.geometry.fov import RectangularFov
from starsense.sensor._fields import check_field
from starsense.sensor.detector import Detector
from starsense.sensor.optics import Optics
from starsense.sensor.psf_spec import PSFSpec

__all__ = ["MAX_FIELD_DEG", "DetectionThresholds", "Sensor"]

#: widest field a sensor may have across either axis, deg (a pinhole camera's field is < 180)
MAX_FIELD_DEG = 175.0


@dataclass(frozen=True, kw_only=True)
class DetectionThresholds:
    """Star-detection logic (Dzamba & Enright 2014, sec. 1.2; ST-16 values by default).

    Attributes
    ----------
    lit_pixel_counts : float
        A pixel is lit when its background-subtracted counts exceed this.
    min_pixels : int
        Minimum number of contiguous lit pixels of a star.
    min_integrated_counts : float
        Minimum summed background-subtracted counts of the star's lit pixels.
    connectivity : int
        4 or 8: which neighbours make pixels contiguous.
    """

    lit_pixel_counts: float = 120.0
    min_pixels: int = 6
    min_integrated_counts: float = 1000.0
    connectivity: int = 8

    def __post_init__(self) -> None:
        # counts: no pixel of a (<= 32-bit) ADC exceeds 2^32, nor a star's sum 2^32 x 1e6 px
        check_field(
            "detection", "lit_pixel_counts", self.lit_pixel_counts, 0, 2.0**32, lo_open=True
        )
        check_field("detection", "min_pixels", self.min_pixels, 1, 1_000_000, integer=True)
        check_field(
            "detection", "min_integrated_counts", self.min_integrated_counts, 0, 2.0**32 * 1e6
        )
        if self.connectivity not in (4, 8):
            raise InputError(f"detection.connectivity must be 4 or 8, got {self.connectivity!r}")


def _check_detection_fits_adc(logic: DetectionThresholds, det: Detector) -> None:
    """Refuse a detection logic the detector's ADC cannot meet, or finer than one count.

    Over the bias, a pixel gives at most ``2**bit_depth - 1 - bias_counts`` counts; a star at
    most that in every pixel of the detector.
    """
    top = det.saturation_counts - det.bias_counts
    if logic.lit_pixel_counts < 1.0:
        raise InputError(
            f"detection.lit_pixel_counts = {logic.lit_pixel_counts:g} is below one ADC count: "
            "no count step is that fine (allowed 1 ... the ADC's top over the bias)"
        )
    if logic.lit_pixel_counts >= top:
        raise InputError(
            f"detection.lit_pixel_counts = {logic.lit_pixel_counts:g} counts: no pixel can "
            f"exceed it: a {det.bit_depth}-bit ADC gives at most {top:g} counts over the bias "
            f"({det.bias_counts:g})"
        )
    if 0.0 < logic.min_integrated_counts < 1.0:
        raise InputError(
            f"detection.min_integrated_counts = {logic.min_integrated_counts:g} is below one "
            "ADC count (0 turns the check off)"
        )
    if logic.min_integrated_counts > top * det.columns * det.rows:
        raise InputError(
            f"detection.min_integrated_counts = {logic.min_integrated_counts:g} counts: more "
            f"than the whole {det.columns} x {det.rows} detector can give at {top:g} counts a "
            "pixel"
        )


@dataclass(frozen=True, kw_only=True)
class Sensor:
    """A star sensor: optics, detector, exposure and detection logic.

    Build it with :func:`~starsense.sensor.load_sensor` from a preset name or a TOML path, or
    directly.

    Parameters
    ----------
    name : str
        Sensor name.
    optics : Optics
        Lens: focal length, aperture, distortion (:mod:`starsense.sensor.optics`).
    detector : Detector
        Pixels, noise, gain and ADC (:mod:`starsense.sensor.detector`).
    exposure_s : float
        Exposure time, s.
    detection : DetectionThresholds
        The detection logic: lit-pixel and integrated thresholds, counts.
    description : str
        Free text from the TOML.
    attitude_areas : AreaLayout or None
        Attitude-determination areas in the focal plane (Lin et al. 2024), tangent-plane units
        (:class:`starsense.geometry.areas.AreaLayout`); None when the whole detector is used.
    quoted, budget : tuple of (key, value)
        The TOML's ``[quoted]`` and ``[budget]`` tables (:mod:`starsense.sensor.quoted`), for the
        datasheet.
    exclusion : Exclusion or None
        Sun, Moon and Earth-limb exclusion half-angles (:mod:`starsense.sensor.exclusion`);
        None when the TOML has no ``[exclusion]`` table.
    mission : MissionPlan or None
        The mission the TOML's ``[mission]`` table names (:mod:`starsense.sensor.mission_plan`),
        for the report's mission section.
    psf : PSFSpec
        The point-spread function's shape (``[psf]``, :mod:`starsense.sensor.psf_spec`); its
        width is ``detector.psf_sigma_px``. Default: a Gaussian.

    Examples
    --------
    >>> from starsense.sensor import load_sensor
    >>> st16 = load_sensor("st16")
    >>> round(st16.focal_length_px)
    7273
    >>> shorter = st16.with_(exposure_s=0.05)  # a changed copy; the sensor is frozen
    """

    name: str
    optics: Optics
    detector: Detector
    exposure_s: float
    detection: DetectionThresholds = field(default_factory=DetectionThresholds)
    description: str = ""
    attitude_areas: Any = None
    quoted: tuple = ()
    budget: tuple = ()
    exclusion: Any = None
    mission: Any = None
    psf: PSFSpec = field(default_factory=PSFSpec)

    def __post_init__(self) -> None:
        if not isinstance(self.psf, PSFSpec):
            raise InputError(f"psf must be a PSFSpec, got {type(self.psf).__name__}")
        for key in ("name", "description"):
            if not isinstance(getattr(self, key), str):
                raise InputError(f"{key} must be text, got {getattr(self, key)!r}")
        check_field("sensor", "exposure_s", self.exposure_s, 0, 1e5, lo_open=True)
        for axis in ("columns", "rows"):
            size_m = getattr(self.detector, axis) * self.detector.pixel_pitch_m
            field_deg = 2.0 * math.degrees(math.atan(size_m / 2.0 / self.optics.focal_length_m))
            if field_deg > MAX_FIELD_DEG:
                raise InputError(
                    f"detector is too large for the focal length: a field of {field_deg:.1f} "
                    f"deg across the {axis} (detector.{axis} x pixel_pitch_m = {size_m:.4g} m "
                    f"at optics.focal_length_m = {self.optics.focal_length_m:g}); a pinhole "
                    f"camera covers less than {MAX_FIELD_DEG:g} deg"
                )
        self._check_distortion_fold()
        _check_detection_fits_adc(self.detection, self.detector)

    def _check_distortion_fold(self) -> None:
        """Refuse distortion that folds back inside the detector (no direction for a pixel)."""
        if not self.optics.has_distortion:
            return
        c, r = self.detector.columns - 1, self.detector.rows - 1
        xs = np.array([0.0, c / 2, c, c, c, c / 2, 0.0, 0.0])
        ys = np.array([0.0, 0.0, 0.0, r / 2, r, r, r, r / 2])
        cx, cy = self.principal_point_px
        fp = self.focal_length_px
        u, w = undistort((xs - cx) / fp, (ys - cy) / fp, self.optics.distortion)
        j = distortion_jacobian(np.nan_to_num(u), np.nan_to_num(w), self.optics.distortion)
        folded = j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0] <= 0
        bad = np.flatnonzero(~(np.isfinite(u) & np.isfinite(w)) | folded)
        if bad.size:
            k1, k2, p1, p2 = self.optics.distortion
            raise InputError(
                f"optics.distortion_k1 = {k1:g}, distortion_k2 = {k2:g}, distortion_p1 = "
                f"{p1:g}, distortion_p2 = {p2:g} fold the image back inside the detector: "
                f"pixel ({xs[bad[0]]:g}, {ys[bad[0]]:g}) lies beyond the fold of the "
                "distortion model, no direction maps to it"
            )

    # -- geometry ----------------------------------------------------------------------------

    @property
    def focal_length_px(self) -> float:
        """Focal length in pixels, f / pitch."""
        return self.optics.focal_length_m / self.detector.pixel_pitch_m

    @property
    def principal_point_px(self) -> tuple[float, float]:
        """(x, y) of the principal point on the detector, pixel-centre convention."""
        return (
            (self.detector.columns - 1) / 2.0 + self.optics.principal_offset_x_px,
            (self.detector.rows - 1) / 2.0 + self.optics.principal_offset_y_px,
        )

    @property
    def half_fov_rad(self) -> tuple[float, float]:
        """Half-angles across columns (x) and rows (y), pinhole model, rad."""
        f = self.optics.focal_length_m
        p = self.detector.pixel_pitch_m
        return (
            math.atan(self.detector.columns * p / 2 / f),
            math.atan(self.detector.rows * p / 2 / f),
        )

    def fov(self):
        """Return the rectangular field of view of the detector (geometry.fov.RectangularFov)."""
        hx, hy = self.half_fov_rad
        return RectangularFov(hx, hy)

    def project(self, vectors_cam) -> tuple[np.ndarray, np.ndarray]:
        """Project camera-frame directions to pixel coordinates, pinhole + distortion.

        The gnomonic step is written out here rather than taken from
        :func:`starsense.geometry.projection.vectors_to_tangent`, which refuses directions
        behind the camera: star tracks need them as NaN.

        Parameters
        ----------
        vectors_cam : array_like, shape (N, 3)
            Directions in the camera frame (need not be unit vectors).

        Returns
        -------
        x, y : ndarray, shape (N,)
            Pixel coordinates; NaN for directions behind the camera (z <= 0).
        """
        v = np.asarray(vectors_cam, dtype=float)
        z = v[..., 2]
        if (z > 0).all():  # every direction in front: no NaN to put in
            u, w = v[..., 0] / z, v[..., 1] / z
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.where(z > 0, v[..., 0] / z, np.nan)
                w = np.where(z > 0, v[..., 1] / z, np.nan)
        if self.optics.has_distortion:
            u, w = distort(u, w, self.optics.distortion)
        cx, cy = self.principal_point_px
        fp = self.focal_length_px
        return cx + fp * u, cy + fp * w

    def unproject(self, x_px, y_px) -> np.ndarray:
        """Return the camera-frame unit vectors of pixel coordinates (inverts the distortion).

        Parameters
        ----------
        x_px, y_px : array_like, shape (N,)
            Finite pixel coordinates.

        Returns
        -------
        ndarray, shape (N, 3)
            Unit vectors in the camera frame.
        """
        cx, cy = self.principal_point_px
        fp = self.focal_length_px
        u = (np.asarray(x_px, dtype=float) - cx) / fp
        w = (np.asarray(y_px, dtype=float) - cy) / fp
        if self.optics.has_distortion:
            u, w = undistort(u, w, self.optics.distortion)
            if not (np.all(np.isfinite(u)) and np.all(np.isfinite(w))):
                raise InputError(
                    "pixel position beyond the fold of the distortion model (optics.distortion_*)"
                )
        # tangent_to_vectors(stack([u, w])) without its copies: the same norm, summed in the
        # same order (u^2 + w^2 + 1), and the same quotients
        norm = np.sqrt(u * u + w * w + 1.0)
        if not np.isfinite(norm).all():
            raise InputError("pixel coordinates must be finite")
        out = np.empty((*norm.shape, 3))
        np.divide(u, norm, out=out[..., 0])
        np.divide(w, norm, out=out[..., 1])
        np.divide(1.0, norm, out=out[..., 2])
        return out

    def exposure_or(self, exposure_s: float | None = None) -> float:
        """Return the exposure to use: ``exposure_s`` if given, else the sensor's own, s.

        Parameters
        ----------
        exposure_s : float or None
            An exposure that overrides the sensor's, s (> 0, finite).

        Raises
        ------
        InputError
            If the given exposure is not a finite number > 0.
        """
        if exposure_s is None:
            return self.exposure_s
        return check_scalar(exposure_s, "exposure_s", 0.0, None, lo_open=True)

    def psf_sigma_at(self, x_px, y_px) -> np.ndarray:
        """Return the Gaussian PSF sigma at detector positions, px.

        ``psf_sigma_px`` at the centre, ``optics.psf_sigma_corner_px`` in the corners (0: the
        same everywhere), growing with the square of the distance from the centre.

        Parameters
        ----------
        x_px, y_px : array_like (N,)
            Column and row, px.

        Returns
        -------
        ndarray (N,)
        """
        det = self.detector
        s0, sc = det.psf_sigma_px, self.optics.psf_sigma_corner_px
        x = np.asarray(x_px, dtype=float)
        if sc <= 0.0 or sc == s0:
            return np.full(x.shape, float(s0))
        cx, cy = 0.5 * (det.columns - 1), 0.5 * (det.rows - 1)
        r2 = ((x - cx) ** 2 + (np.asarray(y_px, dtype=float) - cy) ** 2) / (cx**2 + cy**2)
        return s0 + (sc - s0) * np.minimum(r2, 1.0)

    def streak_length_px(self, rate_rad_s: float) -> float:
        """Length of a cross-axis streak, f tan(|w| t_e) / pitch (Dzamba & Enright eq. 1), px.

        Parameters
        ----------
        rate_rad_s : float
            Cross-axis body rate, rad/s.
        """
        return self.focal_length_px * math.tan(abs(rate_rad_s) * self.exposure_s)

    def roll_arc_px(self, roll_rate_rad_s: float) -> float:
        """Largest roll streak, at the edge of the minor axis: (h/2) tan(|w_z| t_e) (eq. 2), px.

        Parameters
        ----------
        roll_rate_rad_s : float
            Roll rate about the boresight, rad/s.
        """
        h_px = min(self.detector.rows, self.detector.columns)
        return h_px / 2.0 * math.tan(abs(roll_rate_rad_s) * self.exposure_s)

    def with_(self, **changes) -> Sensor:
        """Return a copy with top-level fields replaced (GalSim-style ``with``)."""
        return dataclasses.replace(self, **changes)
