"""Sensor configuration: optics, detector, exposure and detection thresholds, loaded from TOML.

A :class:`Sensor` is immutable and validated on construction: a bad value raises
:class:`~starsense.errors.InputError` naming the field, the value and the allowed range (and the
file, when loaded from TOML). Presets live in ``starsense/sensor/presets/*.toml``; copy one and
edit it to describe your own sensor.

Pixel convention (shared with rendering and detection): pixel centres are at integer
coordinates; pixel (row r, column c) covers x in [c - 0.5, c + 0.5), y in [r - 0.5, r + 0.5).
The boresight (principal point) falls on the centre of the detector,
((columns - 1) / 2, (rows - 1) / 2). Camera frame: +z boresight, +x increasing column,
+y increasing row (see :mod:`starsense.geometry.attitude`).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from starsense.errors import InputError


def _check(owner: str, name: str, value, lo=None, hi=None, *, lo_open=False, hi_open=False,
           integer=False) -> None:  # fmt: skip
    """Raise InputError unless lo <= value <= hi (open ends where asked), finite, integer."""
    label = f"{owner}.{name}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{label} must be a number, got {value!r}")
    if integer and int(value) != value:
        raise InputError(f"{label} must be an integer, got {value!r}")
    if not math.isfinite(value):
        raise InputError(f"{label} must be finite, got {value!r}")
    bad_lo = lo is not None and (value <= lo if lo_open else value < lo)
    bad_hi = hi is not None and (value >= hi if hi_open else value > hi)
    if bad_lo or bad_hi:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        rng = f"{left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}{right}"
        raise InputError(f"{label} = {value!r} is out of range; allowed {rng}")


@dataclass(frozen=True)
class Optics:
    """Pinhole optics with optional radial distortion.

    Attributes
    ----------
    focal_length_m : float
        Effective focal length, m.
    aperture_m : float
        Entrance-pupil diameter D, m.
    transmission : float
        Optical throughput, 0..1 (multiplies the detected photons).
    distortion_k1, distortion_k2 : float
        Radial distortion r_d = r (1 + k1 r^2 + k2 r^4), r the ideal image radius in units of
        the focal length (tan of the off-axis angle).
    """

    focal_length_m: float
    aperture_m: float
    transmission: float = 1.0
    distortion_k1: float = 0.0
    distortion_k2: float = 0.0

    def __post_init__(self) -> None:
        _check("optics", "focal_length_m", self.focal_length_m, 0, 10, lo_open=True)
        _check("optics", "aperture_m", self.aperture_m, 0, 10, lo_open=True)
        _check("optics", "transmission", self.transmission, 0, 1, lo_open=True)
        _check("optics", "distortion_k1", self.distortion_k1, -10, 10)
        _check("optics", "distortion_k2", self.distortion_k2, -10, 10)


@dataclass(frozen=True)
class Detector:
    """Image detector.

    Attributes
    ----------
    columns, rows : int
        Pixels across (x) and down (y).
    pixel_pitch_m : float
        Pixel size, m.
    qe_mean : float
        Mean quantum efficiency over ``passband_nm`` (Reed model; used when no curve is given).
    qe_curve_nm, qe_curve : tuple of float
        Optional QE curve: wavelengths (nm, increasing) and QE (0..1).
    passband_nm : (float, float)
        Wavelength range the detector responds to, nm (paper: 400-800 nm).
    full_well_e : float
        Full-well capacity, electrons (signal clips here before the ADC).
    gain_counts_per_e : float
        Conversion gain, counts per electron.
    read_noise_e : float
        Read noise, electrons rms.
    dark_current_e_s : float
        Dark current, electrons per pixel per second.
    bias_counts : float
        Offset added before quantisation, counts.
    bit_depth : int
        ADC bits (1..32): counts saturate at 2^bits - 1.
    psf_sigma_px : float
        Standard deviation of the static Gaussian PSF, pixels.
    """

    columns: int
    rows: int
    pixel_pitch_m: float
    gain_counts_per_e: float
    read_noise_e: float
    bit_depth: int
    psf_sigma_px: float
    qe_mean: float = 0.5
    qe_curve_nm: tuple[float, ...] = ()
    qe_curve: tuple[float, ...] = ()
    passband_nm: tuple[float, float] = (400.0, 800.0)
    full_well_e: float = 1e5
    dark_current_e_s: float = 0.0
    bias_counts: float = 0.0

    def __post_init__(self) -> None:
        _check("detector", "columns", self.columns, 1, 100_000, integer=True)
        _check("detector", "rows", self.rows, 1, 100_000, integer=True)
        _check("detector", "pixel_pitch_m", self.pixel_pitch_m, 0, 1e-3, lo_open=True)
        _check("detector", "gain_counts_per_e", self.gain_counts_per_e, 0, 1e4, lo_open=True)
        _check("detector", "read_noise_e", self.read_noise_e, 0, 1e4)
        _check("detector", "bit_depth", self.bit_depth, 1, 32, integer=True)
        _check("detector", "psf_sigma_px", self.psf_sigma_px, 0, 100, lo_open=True)
        _check("detector", "qe_mean", self.qe_mean, 0, 1, lo_open=True)
        _check("detector", "full_well_e", self.full_well_e, 0, 1e9, lo_open=True)
        _check("detector", "dark_current_e_s", self.dark_current_e_s, 0, 1e9)
        _check("detector", "bias_counts", self.bias_counts, 0, 2.0**self.bit_depth - 1)
        if len(self.passband_nm) != 2:
            raise InputError(f"detector.passband_nm must be [low, high], got {self.passband_nm!r}")
        lo, hi = self.passband_nm
        _check("detector", "passband_nm[0]", lo, 50, 30000)
        _check("detector", "passband_nm[1]", hi, lo, 30000, lo_open=True)
        if len(self.qe_curve_nm) != len(self.qe_curve):
            raise InputError(
                f"detector.qe_curve_nm ({len(self.qe_curve_nm)} values) and detector.qe_curve "
                f"({len(self.qe_curve)} values) must have the same length"
            )
        if self.qe_curve:
            if len(self.qe_curve) < 2:
                raise InputError("detector.qe_curve needs at least 2 points")
            if np.any(np.diff(self.qe_curve_nm) <= 0):
                raise InputError("detector.qe_curve_nm must be strictly increasing")
            for i, q in enumerate(self.qe_curve):
                _check("detector", f"qe_curve[{i}]", q, 0, 1)

    @property
    def saturation_counts(self) -> int:
        """Largest count the ADC can output, 2^bits - 1."""
        return 2**self.bit_depth - 1

    def qe(self, wavelength_m) -> np.ndarray:
        """QE at the given wavelengths: the curve if given, else ``qe_mean`` inside the passband
        and zero outside it.
        """
        lam_nm = np.asarray(wavelength_m, dtype=float) * 1e9
        if self.qe_curve:
            return np.interp(lam_nm, self.qe_curve_nm, self.qe_curve, left=0.0, right=0.0)
        lo, hi = self.passband_nm
        return np.where((lam_nm >= lo) & (lam_nm <= hi), self.qe_mean, 0.0)

    @property
    def mean_qe(self) -> float:
        """Mean QE over the passband (the Reed model's eta_Q)."""
        if not self.qe_curve:
            return self.qe_mean
        lo, hi = self.passband_nm
        lam = np.linspace(lo, hi, 2001) * 1e-9
        return float(np.mean(self.qe(lam)))


@dataclass(frozen=True)
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
        _check("detection", "lit_pixel_counts", self.lit_pixel_counts, 0, None, lo_open=True)
        _check("detection", "min_pixels", self.min_pixels, 1, 1_000_000, integer=True)
        _check("detection", "min_integrated_counts", self.min_integrated_counts, 0, None)
        if self.connectivity not in (4, 8):
            raise InputError(f"detection.connectivity must be 4 or 8, got {self.connectivity!r}")


@dataclass(frozen=True)
class Sensor:
    """A star sensor: optics, detector, exposure and detection logic.

    Build it with :func:`load_sensor` from a preset name or a TOML path, or directly.
    """

    name: str
    optics: Optics
    detector: Detector
    exposure_s: float
    detection: DetectionThresholds = field(default_factory=DetectionThresholds)
    description: str = ""
    #: attitude-determination areas in the focal plane (Lin et al. 2024), tangent-plane units
    #: (:class:`starsense.geometry.areas.AreaLayout`); None when the whole detector is used
    attitude_areas: Any = None

    def __post_init__(self) -> None:
        _check("sensor", "exposure_s", self.exposure_s, 0, 1e5, lo_open=True)
        if self.detector.rows * self.detector.pixel_pitch_m >= 2 * self.optics.focal_length_m * 20:
            raise InputError("detector is too large for the focal length (field beyond 175 deg)")

    # -- geometry ----------------------------------------------------------------------------

    @property
    def focal_length_px(self) -> float:
        """Focal length in pixels, f / pitch."""
        return self.optics.focal_length_m / self.detector.pixel_pitch_m

    @property
    def principal_point_px(self) -> tuple[float, float]:
        """(x, y) of the boresight on the detector, pixel-centre convention."""
        return (self.detector.columns - 1) / 2.0, (self.detector.rows - 1) / 2.0

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
        """The rectangular field of view of the detector (geometry.fov.RectangularFov)."""
        from starsense.geometry.fov import RectangularFov

        hx, hy = self.half_fov_rad
        return RectangularFov(hx, hy)

    def project(self, vectors_cam) -> tuple[np.ndarray, np.ndarray]:
        """Camera-frame directions (N, 3) -> pixel coordinates x, y (N,), pinhole + distortion.

        Directions behind the camera (z <= 0) give NaN.
        """
        v = np.asarray(vectors_cam, dtype=float)
        z = v[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(z > 0, v[..., 0] / z, np.nan)
            w = np.where(z > 0, v[..., 1] / z, np.nan)
        k1, k2 = self.optics.distortion_k1, self.optics.distortion_k2
        if k1 or k2:
            r2 = u * u + w * w
            s = 1.0 + k1 * r2 + k2 * r2 * r2
            u, w = u * s, w * s
        cx, cy = self.principal_point_px
        fp = self.focal_length_px
        return cx + fp * u, cy + fp * w

    def unproject(self, x_px, y_px) -> np.ndarray:
        """Pixel coordinates -> camera-frame unit vectors (N, 3) (inverts distortion)."""
        cx, cy = self.principal_point_px
        fp = self.focal_length_px
        u = (np.asarray(x_px, dtype=float) - cx) / fp
        w = (np.asarray(y_px, dtype=float) - cy) / fp
        k1, k2 = self.optics.distortion_k1, self.optics.distortion_k2
        if k1 or k2:
            rd = np.hypot(u, w)
            r = rd.copy()
            for _ in range(20):  # fixed-point on r (1 + k1 r^2 + k2 r^4) = rd
                r = rd / (1.0 + k1 * r**2 + k2 * r**4)
            scale = np.divide(r, rd, out=np.ones_like(rd), where=rd > 0)
            u, w = u * scale, w * scale
        v = np.stack([u, w, np.ones_like(u)], axis=-1)
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def streak_length_px(self, rate_rad_s: float) -> float:
        """Length of a cross-axis streak, f tan(|w| t_e) / pitch (Dzamba & Enright eq. 1)."""
        return self.focal_length_px * math.tan(abs(rate_rad_s) * self.exposure_s)

    def roll_arc_px(self, roll_rate_rad_s: float) -> float:
        """Largest roll streak, at the edge of the minor axis: (h/2) tan(|w_z| t_e) (eq. 2), px."""
        h_px = min(self.detector.rows, self.detector.columns)
        return h_px / 2.0 * math.tan(abs(roll_rate_rad_s) * self.exposure_s)

    def with_(self, **changes) -> Sensor:
        """A copy with top-level fields replaced (GalSim-style ``with``)."""
        return dataclasses.replace(self, **changes)


# ---------------------------------------------------------------------------------------------
# TOML

_SECTIONS: dict[str, type] = {
    "optics": Optics,
    "detector": Detector,
    "detection": DetectionThresholds,
}
_TOP_KEYS = {"name", "description", "exposure_s", "attitude_areas", *(_SECTIONS)}
_AREA_KEYS = {"layout", "image_circle_diameter_mm", "area"}
_AREA_SHAPES = ("rectangle_mm", "polygon_mm")


def _number_list(value: Any, where: str, length: int | None = None) -> list[float]:
    ok = isinstance(value, list) and all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    )
    if not ok or (length is not None and len(value) != length):
        size = f"{length} " if length is not None else ""
        raise InputError(f"{where} must be a list of {size}finite numbers, got {value!r}")
    return [float(v) for v in value]


def _areas_from_table(table: Any, detector: Detector, optics: Optics, source: str):
    """The ``[attitude_areas]`` table -> AreaLayout (tangent-plane units = mm / focal mm).

    Either ``layout = "lin2024"`` (the four segments between the square detector and its
    circumscribed circle, Lin et al. 2024, Fig. 1), or ``[[attitude_areas.area]]`` entries with a
    ``name`` and ``rectangle_mm = [x_min, x_max, y_min, y_max]`` or ``polygon_mm = [[x, y], ...]``
    (focal-plane millimetres from the optical axis, x along detector columns), optionally
    checked against ``image_circle_diameter_mm``.
    """
    from starsense.geometry.areas import AreaLayout, FocalArea

    where = f"{source}: [attitude_areas]"
    if not isinstance(table, dict):
        raise InputError(f"{where} must be a table")
    unknown = sorted(set(table) - _AREA_KEYS)
    if unknown:
        raise InputError(
            f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_AREA_KEYS))}"
        )
    f_mm = optics.focal_length_m * 1e3
    layout = table.get("layout")
    if layout is not None:
        if layout != "lin2024":
            raise InputError(f"{where}: layout = {layout!r} is not known; use lin2024")
        if "area" in table:
            raise InputError(f"{where}: give either layout or [[attitude_areas.area]], not both")
        if detector.columns != detector.rows:
            raise InputError(
                f"{where}: layout lin2024 needs a square detector, got "
                f"{detector.columns} x {detector.rows}"
            )
        half_mm = detector.columns * detector.pixel_pitch_m * 1e3 / 2.0
        return AreaLayout.lin2024(half_mm / f_mm)
    entries = table.get("area")
    if not isinstance(entries, list) or not entries:
        raise InputError(f'{where} needs layout = "lin2024" or [[attitude_areas.area]] entries')
    areas = []
    for i, entry in enumerate(entries, start=1):
        at = f"{where} area {i}"
        if not isinstance(entry, dict):
            raise InputError(f"{at} must be a table")
        extra = sorted(set(entry) - {"name", *_AREA_SHAPES})
        if extra:
            raise InputError(f"{at}: unknown key(s) {', '.join(extra)}")
        shapes = [k for k in _AREA_SHAPES if k in entry]
        if len(shapes) != 1:
            raise InputError(f"{at} needs exactly one of {', '.join(_AREA_SHAPES)}")
        name = str(entry.get("name", i))
        if shapes[0] == "rectangle_mm":
            x0, x1, y0, y1 = _number_list(entry["rectangle_mm"], f"{at} rectangle_mm", 4)
            if not (x0 < x1 and y0 < y1):
                raise InputError(f"{at} rectangle_mm needs x_min < x_max and y_min < y_max")
            vertices = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
        else:
            poly = entry["polygon_mm"]
            if not isinstance(poly, list):
                raise InputError(f"{at} polygon_mm must be a list of [x, y] pairs")
            vertices = [_number_list(v, f"{at} polygon_mm vertex", 2) for v in poly]
        try:
            areas.append(FocalArea(name, np.asarray(vertices) / f_mm))
        except InputError as exc:
            raise InputError(f"{at}: {exc}") from None
    radius = None
    if "image_circle_diameter_mm" in table:
        d = table["image_circle_diameter_mm"]
        _check("attitude_areas", "image_circle_diameter_mm", d, 0, None, lo_open=True)
        radius = d / 2.0 / f_mm
    try:
        return AreaLayout(tuple(areas), lens_radius=radius)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


_TUPLE_FIELDS = {"qe_curve_nm", "qe_curve", "passband_nm"}


def _build(cls: type, table: Any, section: str, source: str):
    if not isinstance(table, dict):
        raise InputError(f"{source}: [{section}] must be a table")
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - known)
    if unknown:
        raise InputError(
            f"{source}: unknown key(s) {', '.join(unknown)} in [{section}]; "
            f"known keys: {', '.join(sorted(known))}"
        )
    required = [
        f.name
        for f in dataclasses.fields(cls)
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    missing = [k for k in required if k not in table]
    if missing:
        raise InputError(f"{source}: missing key(s) {', '.join(missing)} in [{section}]")
    kwargs = {k: tuple(v) if k in _TUPLE_FIELDS else v for k, v in table.items()}
    try:
        return cls(**kwargs)
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def sensor_from_dict(data: dict, source: str = "<dict>") -> Sensor:
    """Build a validated :class:`Sensor` from the parsed TOML structure."""
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise InputError(
            f"{source}: unknown top-level key(s) {', '.join(unknown)}; "
            f"known: {', '.join(sorted(_TOP_KEYS))}"
        )
    for key in ("optics", "detector", "exposure_s"):
        if key not in data:
            raise InputError(f"{source}: missing {key!r}")
    parts = {s: _build(cls, data.get(s, {}), s, source) for s, cls in _SECTIONS.items()}
    areas = None
    if "attitude_areas" in data:
        areas = _areas_from_table(
            data["attitude_areas"], parts["detector"], parts["optics"], source
        )
    try:
        return Sensor(
            name=str(data.get("name", Path(source).stem)),
            description=str(data.get("description", "")),
            exposure_s=data["exposure_s"],
            attitude_areas=areas,
            **parts,
        )
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def preset_names() -> list[str]:
    """Names of the presets shipped inside the package."""
    folder = resources.files("starsense.sensor") / "presets"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_sensor(name_or_path: str | Path) -> Sensor:
    """A sensor from a preset name (``st16``, ``esa_blackfly``, ...) or a TOML file path."""
    text = str(name_or_path)
    path = Path(text)
    if text in preset_names():
        resource = resources.files("starsense.sensor") / "presets" / f"{text}.toml"
        raw, source = resource.read_text(encoding="utf-8"), f"preset {text}"
    elif path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise InputError(f"sensor file not found: {path}")
        raw, source = path.read_text(encoding="utf-8"), str(path)
    else:
        raise InputError(
            f"unknown sensor {text!r}: not a preset ({', '.join(preset_names())}) nor a TOML file"
        )
    try:
        data = tomllib.loads(raw)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: not valid TOML: {exc}") from None
    return sensor_from_dict(data, source)
