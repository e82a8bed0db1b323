"""Sensors from TOML: presets shipped in ``starsense/sensor/presets/*.toml`` or the user's files.

The TOML has the top-level keys ``name``, ``description`` and ``exposure_s`` and the tables
``[optics]``, ``[detector]`` and ``[detection]`` (the fields of :class:`Optics`,
:class:`Detector` and :class:`DetectionThresholds`), optionally ``[attitude_areas]`` and
``[exclusion]`` (bright-body exclusion, :mod:`starsense.sensor.exclusion`) and ``[mission]``
(a mission for the report, :mod:`starsense.sensor.mission_plan`), and ``[provenance]``
(where measured values came from, as ``starsense characterize`` writes it: read as information
only, never as a value of the sensor). Copy a
preset and edit it to describe your own sensor. A bad value raises
:class:`~starsense.errors.InputError` naming the file, the field, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import math
import os
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from starsense._io import read_text
from starsense._io.toml import parse_toml
from starsense._validate import name_keys, show
from starsense.errors import InputError
from starsense.geometry.areas import AreaLayout, FocalArea
from starsense.sensor._fields import check_field
from starsense.sensor.detector import Detector
from starsense.sensor.exclusion import exclusion_from_table
from starsense.sensor.mission_plan import mission_from_table
from starsense.sensor.optics import Optics
from starsense.sensor.psf_spec import PSFSpec, psf_from_table
from starsense.sensor.quoted import parse_budget, parse_quoted
from starsense.sensor.sensor import DetectionThresholds, Sensor

__all__ = ["load_sensor", "preset_names", "sensor_from_dict"]

_SECTIONS: dict[str, type] = {
    "optics": Optics,
    "detector": Detector,
    "detection": DetectionThresholds,
}
_TOP_KEYS = {
    "name", "description", "exposure_s", "attitude_areas", "exclusion", "mission", "quoted",
    "budget", "psf", "provenance", *(_SECTIONS),
}  # fmt: skip
_AREA_KEYS = {"layout", "image_circle_diameter_mm", "area"}
_AREA_SHAPES = ("rectangle_mm", "polygon_mm")
_TUPLE_FIELDS = {"qe_curve_nm", "qe_curve", "passband_nm"}


def _number_list(value: Any, where: str, length: int | None = None) -> list[float]:
    """Return a TOML list of finite numbers (of ``length`` items if given) as floats."""
    ok = isinstance(value, list) and all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    )
    if not ok or (length is not None and len(value) != length):
        size = f"{length} " if length is not None else ""
        raise InputError(f"{where} must be a list of {size}finite numbers, got {value!r}")
    return [float(v) for v in value]


def _area_vertices(entry: Any, at: str) -> list:
    """Return the vertices (mm) of one ``[[attitude_areas.area]]`` entry."""
    if not isinstance(entry, dict):
        raise InputError(f"{at} must be a table")
    extra = sorted(set(entry) - {"name", *_AREA_SHAPES})
    if extra:
        raise InputError(f"{at}: unknown key(s) {name_keys(extra)}")
    shapes = [k for k in _AREA_SHAPES if k in entry]
    if len(shapes) != 1:
        raise InputError(f"{at} needs exactly one of {', '.join(_AREA_SHAPES)}")
    if shapes[0] == "rectangle_mm":
        x0, x1, y0, y1 = _number_list(entry["rectangle_mm"], f"{at} rectangle_mm", 4)
        if not (x0 < x1 and y0 < y1):
            raise InputError(f"{at} rectangle_mm needs x_min < x_max and y_min < y_max")
        return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
    poly = entry["polygon_mm"]
    if not isinstance(poly, list):
        raise InputError(f"{at} polygon_mm must be a list of [x, y] pairs")
    return [_number_list(v, f"{at} polygon_mm vertex", 2) for v in poly]


def _areas_from_table(table: Any, detector: Detector, optics: Optics, source: str):
    """Convert the ``[attitude_areas]`` table to an AreaLayout (tangent-plane units).

    Either ``layout = "lin2024"`` (the four segments between the square detector and its
    circumscribed circle, Lin et al. 2024, Fig. 1), or ``[[attitude_areas.area]]`` entries with a
    ``name`` and ``rectangle_mm = [x_min, x_max, y_min, y_max]`` or ``polygon_mm = [[x, y], ...]``
    (focal-plane millimetres from the optical axis, x along detector columns), optionally
    checked against ``image_circle_diameter_mm``. Tangent-plane units are mm / focal mm.
    """
    where = f"{source}: [attitude_areas]"
    if not isinstance(table, dict):
        raise InputError(f"{where} must be a table")
    unknown = sorted(set(table) - _AREA_KEYS)
    if unknown:
        raise InputError(
            f"{where}: unknown key(s) {name_keys(unknown)}; known: {', '.join(sorted(_AREA_KEYS))}"
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
        vertices = _area_vertices(entry, at)
        try:
            areas.append(FocalArea(str(entry.get("name", i)), np.asarray(vertices) / f_mm))
        except InputError as exc:
            raise InputError(f"{at}: {exc}") from None
    radius = None
    if "image_circle_diameter_mm" in table:
        d = table["image_circle_diameter_mm"]
        check_field("attitude_areas", "image_circle_diameter_mm", d, 0, None, lo_open=True)
        radius = d / 2.0 / f_mm
    try:
        return AreaLayout(tuple(areas), lens_radius=radius)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def _build(cls: type, table: Any, section: str, source: str):
    """Build one section's dataclass from its TOML table (unknown and missing keys named)."""
    if not isinstance(table, dict):
        raise InputError(f"{source}: [{section}] must be a table")
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - known)
    if unknown:
        raise InputError(
            f"{source}: unknown key(s) {name_keys(unknown)} in [{section}]; "
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
    for k in _TUPLE_FIELDS & set(table):
        if not isinstance(table[k], list):
            raise InputError(
                f"{source}: [{section}] {k} must be a list of numbers, e.g. {k} = [400.0, 800.0]; "
                f"got {show(table[k])}"
            )
    kwargs = {k: tuple(v) if k in _TUPLE_FIELDS else v for k, v in table.items()}
    try:
        return cls(**kwargs)
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def sensor_from_dict(data: dict, source: str = "<dict>") -> Sensor:
    """Build a validated :class:`Sensor` from the parsed TOML structure.

    Parameters
    ----------
    data : dict
        The TOML document, as :func:`tomllib.loads` returns it.
    source : str
        Where it came from, for messages (a file name or ``preset NAME``); its stem is the
        sensor's name when ``data`` has none.

    Returns
    -------
    Sensor

    Raises
    ------
    InputError
        ``data`` is not a table, or a key or value is wrong (the message names ``source``,
        the field and the value).
    """
    if not isinstance(data, dict):
        raise InputError(
            f"{source}: a sensor must be a table (a dict of the TOML's keys), "
            f"got {type(data).__name__}"
        )
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise InputError(
            f"{source}: unknown top-level key(s) {name_keys(unknown)}; "
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
    exclusion = None
    if "exclusion" in data:
        exclusion = exclusion_from_table(data["exclusion"], source)
    mission = None
    if "mission" in data:
        mission = mission_from_table(data["mission"], source)
    quoted = parse_quoted(data["quoted"], source) if "quoted" in data else ()
    budget = parse_budget(data["budget"], source) if "budget" in data else ()
    psf = psf_from_table(data["psf"], source) if "psf" in data else PSFSpec()
    if "provenance" in data and not isinstance(data["provenance"], dict):
        raise InputError(f"{source}: [provenance] must be a table, got {show(data['provenance'])}")
    try:
        return Sensor(
            name=data.get("name", Path(source).stem),
            description=data.get("description", ""),
            exposure_s=data["exposure_s"],
            attitude_areas=areas,
            quoted=quoted,
            budget=budget,
            exclusion=exclusion,
            mission=mission,
            psf=psf,
            **parts,
        )
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def preset_names() -> list[str]:
    """Names of the presets shipped inside the package."""
    folder = resources.files("starsense.sensor") / "presets"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_sensor(name_or_path: str | Path) -> Sensor:
    """Load a sensor from a preset name (``st16``, ``esa_blackfly``, ...) or a TOML file path.

    A preset is a TOML file inside the package (``starsense/sensor/presets``): copy one and
    edit it to describe another sensor. Degrees in the TOML become radians here, once.

    Parameters
    ----------
    name_or_path : str or Path
        A name from :func:`preset_names`, or the path of a TOML file.

    Returns
    -------
    Sensor
        The frozen, validated sensor (optics, detector, exposure, detection logic).

    Raises
    ------
    InputError
        An empty or unknown name, an unreadable file, invalid TOML, or a value out of range
        (the message names the table, the key, the value and the allowed range).

    Examples
    --------
    >>> from starsense.sensor import load_sensor
    >>> sensor = load_sensor("st16")
    >>> sensor.detector.columns, sensor.exposure_s
    (2592, 0.1)
    """
    if not isinstance(name_or_path, str | os.PathLike):
        raise InputError(
            "sensor must be a Sensor, a preset name or a sensor TOML path, got "
            f"{type(name_or_path).__name__} {show(name_or_path)}"
        )
    text = str(name_or_path)
    path = Path(text).expanduser()
    if not text.strip():
        raise InputError(
            f"sensor is empty: give a preset ({', '.join(preset_names())}) or a TOML file"
        )
    if text in preset_names():
        resource = resources.files("starsense.sensor") / "presets" / f"{text}.toml"
        raw, source = resource.read_text(encoding="utf-8"), f"preset {text}"
    elif path.suffix == ".toml" or path.exists():
        raw, source = read_text(path, "sensor file"), str(path)
    else:
        raise InputError(
            f"unknown sensor {text!r}: not a preset ({', '.join(preset_names())}) nor a TOML file"
        )
    return sensor_from_dict(parse_toml(raw, source, invalid="not valid TOML"), source)
