"""The sensor file reference (docs/guides/sensor-reference.md) lists what the loader accepts.

Both ways: every key the loader accepts has a row in its table's section, and every row names a
key the loader accepts; the defaults written there are the code's; and the page's TOML
examples load (a partial one on top of the st16 preset).
"""

from __future__ import annotations

import copy
import dataclasses
import re
import tomllib
from pathlib import Path

import pytest

from starsense.analysis.trade import base_document
from starsense.sensor import load as loader
from starsense.sensor.detector import Detector
from starsense.sensor.exclusion import EXCLUSION_KEYS
from starsense.sensor.load import sensor_from_dict
from starsense.sensor.mission_plan import MISSION_KEYS, MissionPlan
from starsense.sensor.optics import Optics
from starsense.sensor.psf_spec import _KEYS as PSF_KEYS
from starsense.sensor.psf_spec import PSFSpec
from starsense.sensor.quoted import _FLAGS, BUDGET_KEYS, QUOTED_KEYS
from starsense.sensor.sensor import DetectionThresholds

PAGE = Path(__file__).resolve().parents[2] / "docs" / "guides" / "sensor-reference.md"
TOP_SCALARS = {"name", "description", "exposure_s"}

pytestmark = pytest.mark.skipif(not PAGE.is_file(), reason="no manual beside the tests")


def _fields(cls) -> set[str]:
    return {f.name for f in dataclasses.fields(cls)}


#: section of the page -> the keys the loader accepts there
ACCEPTED = {
    "top": TOP_SCALARS,
    "optics": _fields(Optics),
    "detector": _fields(Detector),
    "detection": _fields(DetectionThresholds),
    "psf": set(PSF_KEYS),
    "exclusion": set(EXCLUSION_KEYS),
    "attitude_areas": loader._AREA_KEYS | {"name", *loader._AREA_SHAPES},
    "mission": set(MISSION_KEYS),
    "quoted": set(QUOTED_KEYS) | {"source"},
    "budget": set(BUDGET_KEYS) | set(_FLAGS) | {"source"},
    "provenance": set(),  # any table: information only
}
#: section -> the class whose field defaults the page states
DEFAULTS = {
    "optics": Optics,
    "detector": Detector,
    "detection": DetectionThresholds,
    "psf": PSFSpec,
    "mission": MissionPlan,
}


def _rows() -> dict[str, dict[str, list[str]]]:
    """Section -> {key: [unit, default, range, meaning]} of the page's tables."""
    out: dict[str, dict[str, list[str]]] = {}
    section = None
    for line in PAGE.read_text().splitlines():
        head = re.match(r"^## (?:`\[(\w+)\]`|(Top level))", line)
        if head:
            section = head.group(1) or "top"
            out[section] = {}
        elif line.startswith("## "):
            section = None
        row = re.match(r"^\| `(\w+)` \|(.*)\|$", line)
        if row and section is not None:
            out[section][row.group(1)] = [c.strip() for c in row.group(2).split("|")]
    return out


def test_every_accepted_key_is_in_the_reference_and_nothing_else():
    rows = _rows()
    tables = (loader._TOP_KEYS - TOP_SCALARS) | {"top"}
    assert set(rows) == tables, "a table the loader accepts has no section (or the reverse)"
    for section, keys in ACCEPTED.items():
        assert set(rows[section]) == keys, section


def _value(cell: str):
    text = cell.strip().strip("`")
    if text.startswith("["):
        return tuple(float(v) for v in text.strip("[]").split(",") if v.strip())
    if text.startswith('"'):
        return text.strip('"')
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        return text


@pytest.mark.parametrize("section", sorted(DEFAULTS))
def test_defaults_are_the_codes(section):
    rows = _rows()[section]
    for f in dataclasses.fields(DEFAULTS[section]):
        if f.name not in rows:
            continue  # a field the TOML does not set directly (psf samples, source)
        cell = rows[f.name][1]
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            assert cell == "required", f"{section}.{f.name}: {cell}"
            continue
        code = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        if section == "mission" and f.name == "heads":
            assert cell.startswith('`[""]`')
            continue
        code = tuple(float(v) for v in code) if isinstance(code, tuple) else code
        written = _value(cell)
        assert written == code, f"{section}.{f.name}: page {cell!r}, code {code!r}"


def _merge(base: dict, extra: dict) -> dict:
    out = copy.deepcopy(base)
    for key, value in extra.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def test_examples_load():
    blocks = re.findall(r"```toml\n(.*?)```", PAGE.read_text(), flags=re.S)
    assert len(blocks) >= 3
    base = base_document("st16")
    for k, block in enumerate(blocks):
        doc = tomllib.loads(block)
        sensor_from_dict(doc if "exposure_s" in doc else _merge(base, doc), f"example {k}")
