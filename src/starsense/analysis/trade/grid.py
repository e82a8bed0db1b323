"""The designs of a trade: a base sensor TOML, the keys varied, and the grid they span.

A key is a sensor TOML field written as its path: ``exposure_s`` (top level),
``optics.focal_length_m``, ``detector.pixel_pitch_m``, ``detection.lit_pixel_counts``. A
specification is a list (``0.05,0.1,0.2``) or a range ``START:STOP:N`` (N >= 2 values,
both ends included; ``START:STOP:1`` is refused as a zero-step range). Several keys span the
full grid (their product). Coupled keys (``keep``):

* ``f_number``: the aperture follows the focal length (D = f / N of the base), unless the
  aperture is itself varied;
* ``fov``: the field stays that of the base: a varied focal length scales the pixel pitch
  with it (same columns and rows), a varied pixel pitch scales the focal length.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from starsense._io import read_text
from starsense._io.toml import parse_toml
from starsense.errors import InputError
from starsense.sensor import Sensor
from starsense.sensor.detector import Detector
from starsense.sensor.load import preset_names, sensor_from_dict
from starsense.sensor.optics import Optics
from starsense.sensor.sensor import DetectionThresholds

__all__ = [
    "KEEP",
    "MAX_DESIGNS_IN_PROCESS",
    "MAX_DESIGNS_ON_CLUSTER",
    "Design",
    "base_document",
    "check_grid_size",
    "designs",
    "grid_size",
    "parse_vary",
]

#: the coupled keys :func:`designs` knows
KEEP = ("f_number", "fov")
#: the largest grid run in one process; bigger grids need a Dask cluster
MAX_DESIGNS_IN_PROCESS = 10_000
#: the largest grid at all (on a cluster too): this process holds every design's TOML document
#: and row (a few KB each), so 100,000 designs stay within ~0.5 GB here
MAX_DESIGNS_ON_CLUSTER = 100_000
_SECTIONS = {"optics": Optics, "detector": Detector, "detection": DetectionThresholds}
_TOP = ("exposure_s",)


@dataclass(frozen=True)
class Design:
    """One design of a trade.

    Attributes
    ----------
    index : int
        Its row, in grid order.
    values : dict
        The varied keys and their values (TOML units), including the coupled ones.
    document : dict
        The full sensor TOML document of the design.
    """

    index: int
    values: dict
    document: dict

    def sensor(self) -> Sensor:
        """Return the validated sensor (raises :class:`InputError` naming the bad field)."""
        return sensor_from_dict(self.document, source=f"design {self.index}")


def base_document(spec: str | Path) -> dict:
    """Return the TOML document of a preset name or a sensor TOML file.

    Parameters
    ----------
    spec : str or Path
        A preset name (``st16``) or the path of a sensor TOML file.

    Returns
    -------
    dict
        As :func:`tomllib.loads` returns it (validated by loading it once).
    """
    text_spec = str(spec)
    if text_spec in preset_names():
        text = (resources.files("starsense.sensor") / "presets" / f"{text_spec}.toml").read_text()
        source = f"preset {text_spec}"
    else:
        text, source = read_text(Path(text_spec)), text_spec
    doc = parse_toml(text, source)
    doc.setdefault("name", Path(text_spec).stem)
    sensor_from_dict(doc, source=source)
    return doc


def _check_key(key: str) -> tuple[str | None, str]:
    parts = key.split(".")
    if len(parts) == 1 and key in _TOP:
        return None, key
    if len(parts) == 2 and parts[0] in _SECTIONS:
        fields = {f.name for f in dataclasses.fields(_SECTIONS[parts[0]])}
        if parts[1] in fields:
            return parts[0], parts[1]
    known = [*_TOP, *(f"{s}.{f.name}" for s, c in _SECTIONS.items() for f in dataclasses.fields(c))]
    raise InputError(f"--vary: unknown key {key!r}; known keys: {', '.join(known)}")


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"--vary {where}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(f"--vary {where}: {text!r} is not a finite number")
    return value


def parse_vary(text: str) -> tuple[str, list[float]]:
    """Return the key and values of one ``KEY=SPEC`` (see the module docstring).

    Parameters
    ----------
    text : str
        ``KEY=v1,v2,...`` or ``KEY=START:STOP:N``.

    Returns
    -------
    key : str
    values : list of float
    """
    key, sep, spec = text.partition("=")
    key, spec = key.strip(), spec.strip()
    if not sep or not key or not spec:
        raise InputError(f"--vary {text!r}: expected KEY=LIST or KEY=START:STOP:N")
    _check_key(key)
    if ":" in spec:
        parts = spec.split(":")
        if len(parts) != 3:
            raise InputError(f"--vary {key}: range {spec!r} must be START:STOP:N")
        lo, hi = _number(parts[0], key), _number(parts[1], key)
        n = _number(parts[2], key)
        if n != int(n) or n < 2:
            raise InputError(
                f"--vary {key}: range {spec!r} has {parts[2]} steps; N must be an integer >= 2"
            )
        if n > MAX_DESIGNS_ON_CLUSTER:  # sized before it is expanded
            raise InputError(
                f"--vary {key}: range {spec!r} has {int(n):,} values, more than a grid may hold "
                f"({MAX_DESIGNS_ON_CLUSTER:,} designs); use fewer steps"
            )
        if lo == hi:
            raise InputError(f"--vary {key}: range {spec!r} has zero width (START == STOP)")
        n = int(n)
        return key, [lo + (hi - lo) * k / (n - 1) for k in range(n)]
    if spec.count(",") >= MAX_DESIGNS_ON_CLUSTER:
        raise InputError(
            f"--vary {key}: the list has more values than a grid may hold "
            f"({MAX_DESIGNS_ON_CLUSTER:,} designs); give fewer"
        )
    values = [_number(v.strip(), key) for v in spec.split(",") if v.strip()]
    if not values:
        raise InputError(f"--vary {key}: empty list")
    return key, values


def _set(doc: dict, key: str, value: float) -> None:
    section, name = _check_key(key)
    if section is None:
        doc[name] = value
    else:
        doc.setdefault(section, {})[name] = value


def _couple(doc: dict, base: dict, varied: dict, keep: tuple[str, ...]) -> dict:
    """Apply the coupled keys; return the values they set."""
    out = {}
    f0 = base["optics"]["focal_length_m"]
    p0 = base["detector"]["pixel_pitch_m"]
    if "fov" in keep:
        if "optics.focal_length_m" in varied and "detector.pixel_pitch_m" not in varied:
            out["detector.pixel_pitch_m"] = p0 * varied["optics.focal_length_m"] / f0
        elif "detector.pixel_pitch_m" in varied and "optics.focal_length_m" not in varied:
            out["optics.focal_length_m"] = f0 * varied["detector.pixel_pitch_m"] / p0
    if "f_number" in keep and "optics.aperture_m" not in varied:
        f = out.get("optics.focal_length_m", varied.get("optics.focal_length_m", f0))
        out["optics.aperture_m"] = base["optics"]["aperture_m"] * f / f0
    for k, v in out.items():
        _set(doc, k, v)
    return out


def designs(
    base: dict,
    vary: list[tuple[str, list[float]]],
    *,
    keep=(),
    max_designs: int = MAX_DESIGNS_ON_CLUSTER,
) -> list[Design]:
    """Return the designs of the grid spanned by ``vary`` around ``base``.

    Parameters
    ----------
    base : dict
        The base sensor TOML document (:func:`base_document`).
    vary : list of (key, values)
        From :func:`parse_vary`; each key at most once.
    keep : sequence of str
        Coupled quantities kept at the base's value (:data:`KEEP`).
    max_designs : int
        The largest grid accepted, checked before any design is built (default
        :data:`MAX_DESIGNS_ON_CLUSTER`; :data:`MAX_DESIGNS_IN_PROCESS` without a cluster).

    Returns
    -------
    list of Design
        The product of the values, the first key varying slowest. Each design's document is
        not validated here (:meth:`Design.sensor` does it, so one bad design is one bad row).
    """
    keys = [k for k, _ in vary]
    dup = {k for k in keys if keys.count(k) > 1}
    if dup:
        raise InputError(f"--vary: key {sorted(dup)[0]!r} given twice")
    bad = [k for k in keep if k not in KEEP]
    if bad:
        raise InputError(f"--keep: unknown {bad[0]!r}; known: {', '.join(KEEP)}")
    n = check_grid_size(vary, max_designs)
    out = []
    name = str(base.get("name", "design"))
    for i, combo in enumerate(itertools.product(*(v for _, v in vary))):
        doc = {k: dict(v) if isinstance(v, dict) else v for k, v in base.items()}
        varied = dict(zip(keys, combo, strict=True))
        for k, v in varied.items():
            _set(doc, k, v)
        coupled = _couple(doc, base, varied, tuple(keep))
        doc["name"] = f"{name}-{i:0{len(str(n))}d}"
        out.append(Design(i, {**varied, **coupled}, doc))
    return out


def grid_size(vary: list[tuple[str, list[float]]]) -> int:
    """Return the number of designs of a grid (the product of the value counts)."""
    return math.prod(len(v) for _, v in vary)


def check_grid_size(vary: list[tuple[str, list[float]]], max_designs: int) -> int:
    """Return the grid's number of designs, refused when above ``max_designs`` (none built).

    Raises
    ------
    InputError
        Naming the grid's size, its cap and what to do.
    """
    n = grid_size(vary)
    if n > max_designs:
        shape = " x ".join(f"{len(v):,}" for _, v in vary)
        hint = (
            "run it on a cluster (--dask ADDRESS) or narrow it"
            if max_designs < MAX_DESIGNS_ON_CLUSTER
            else "narrow it (several runs)"
        )
        raise InputError(
            f"the grid has {n:,} designs ({shape}), more than {max_designs:,}"
            f"{' without --dask' if max_designs < MAX_DESIGNS_ON_CLUSTER else ''}; {hint}"
        )
    return n
