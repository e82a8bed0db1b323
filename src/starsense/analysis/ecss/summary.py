"""The vendor-style one-page summary of a sensor: what a star tracker's datasheet front page says.

:func:`vendor_summary` reads a datasheet (its JSON form,
:meth:`starsense.analysis.datasheet.Datasheet.to_dict`) and its ECSS statement's rows
(:func:`starsense.analysis.ecss.export.statement_rows`) and gives the lines a vendor prints on
the first page: accuracy per axis at the stated confidence, inertial and at each rate; the
fastest rate tracking keeps; lost in space's success and time; the update rate; sky coverage;
the exclusion angles; mass and power as the user gives them. Each line says where its number
comes from (the prediction, this run's frames, the sensor file, the user); a number nobody
gave is "not given", never a guess.
"""

from __future__ import annotations

import math

from starsense.units import RAD_TO_DEG

__all__ = ["vendor_summary"]


def _fmt(x, spec: str) -> str:
    return "n/a" if x is None or not math.isfinite(x) else format(x, spec)


def _accuracy_lines(rows: list[dict], confidence: float) -> list[dict]:
    """Return per rate the statement's totals on X, Y and Z (inertial pointing or slewing)."""
    totals: dict = {}
    for r in rows:
        if r["class"] == "total":
            totals.setdefault(r["rate_deg_s"], {})[r["axis"]] = r["value_arcsec"]
    out = []
    for rate, axes in sorted(totals.items()):
        use = "inertial pointing" if rate == 0.0 else f"slewing at {rate:g} deg/s"
        out.append(
            {
                "item": f"accuracy X / Y / Z, {use} ({100 * confidence:.4g} %)",
                "value": " / ".join(_fmt(axes.get(a), ".3g") for a in ("X", "Y", "Z")),
                "unit": "arcsec",
                "source": "ECSS statement (forward model, the sensor's sky)",
                "key": f"accuracy_{'rest' if rate == 0.0 else f'{rate:g}_deg_s'}_arcsec",
                "values": [axes.get(a) for a in ("X", "Y", "Z")],
            }
        )
    return out


def _number(item: str, key: str, value, spec: str, unit: str, source: str) -> dict:
    """Return a line of one number (``spec`` its text format; None or NaN print "n/a")."""
    text = _fmt(value, spec)
    return {"item": item, "value": text, "unit": unit, "source": source, "key": key,
            "values": [value]}  # fmt: skip


def _given(value, unit: str, item: str, key: str) -> dict:
    text = "not given" if value is None else format(float(value), ".4g")
    return {
        "item": item,
        "value": text,
        "unit": "" if value is None else unit,
        "source": "given by the user" if value is not None else "not given (--mass-kg, --power-w)",
        "key": key,
        "values": [None if value is None else float(value)],
    }


def _exclusion_line(exclusion) -> dict:
    if exclusion is None:
        return {
            "item": "exclusion half-angles Sun / Moon / Earth limb",
            "value": "not given",
            "unit": "",
            "source": "the sensor file has no [exclusion] table",
            "key": "exclusion_deg",
            "values": [None, None, None],
        }
    angles = [getattr(exclusion, name, None) for name in ("sun_rad", "moon_rad", "earth_limb_rad")]
    deg = [None if a is None else a * RAD_TO_DEG for a in angles]
    return {
        "item": "exclusion half-angles Sun / Moon / Earth limb",
        "value": " / ".join(_fmt(d, ".3g") for d in deg),
        "unit": "deg",
        "source": "the sensor file's [exclusion]",
        "key": "exclusion_deg",
        "values": deg,
    }


def vendor_summary(
    sheet: dict, statement_rows: list[dict], *, confidence: float, sensor, mass_kg=None,
    power_w=None,
) -> dict:  # fmt: skip
    """Return the one-page summary of a sensor (module docstring).

    Parameters
    ----------
    sheet : dict
        The datasheet's JSON form.
    statement_rows : list of dict
        Its statement's rows (:func:`~starsense.analysis.ecss.export.statement_rows`).
    confidence : float
        The statement's confidence (probability).
    sensor : Sensor
        The sensor (its exposure and exclusion angles).
    mass_kg, power_w : float, optional
        Given by the user (not modelled).

    Returns
    -------
    dict
        ``sensor``, ``confidence`` and ``lines``: each ``item``, ``value`` (text), ``unit``,
        ``source``, ``key`` (stable snake_case) and ``values`` (the numbers, None: not known).
    """
    av = sheet.get("availability") or {}
    mc = sheet.get("monte_carlo") or {}
    fastest = ((av.get("fastest_rate_deg_s") or {}).get("tracking") or {}).get("99")
    frames, solved = mc.get("frames") or 0, mc.get("solved")
    success = solved / frames if frames and solved is not None else None
    lines = [
        {
            "item": "field of view",
            "value": " x ".join(_fmt(f, ".3g") for f in sheet["fov_deg"]),
            "unit": "deg",
            "source": "the sensor file",
            "key": "fov_deg",
            "values": list(sheet["fov_deg"]),
        },
        *_accuracy_lines(statement_rows, confidence),
        _number(
            "maximum tracking rate (tracking kept on 99 % of the sky)",
            "max_tracking_rate_deg_s",
            fastest,
            ".3g",
            "deg/s",
            "predicted: availability under slew (the datasheet's)",
        ),
        {
            "item": "lost in space success at rest",
            "value": f"{_fmt(success, '.3f')} (predicted {_fmt(av.get('lost_in_space'), '.3f')})",
            "unit": "fraction",
            "source": f"measured on {frames} rendered frames; predicted: the sky's availability",
            "key": "lost_in_space_success_fraction",
            "values": [success, av.get("lost_in_space")],
        },
        _number(
            "lost in space time, median",
            "lost_in_space_time_ms",
            mc.get("median_ms"),
            ".3g",
            "ms",
            "measured on this machine, one thread, the rendered frames",
        ),
        _number(
            "update rate (one attitude a frame)",
            "update_rate_hz",
            1.0 / sensor.exposure_s,
            ".3g",
            "Hz",
            "the sensor file's exposure (readout and processing not modelled)",
        ),
        _number(
            "sky coverage (lost in space at rest)",
            "sky_coverage_fraction",
            av.get("lost_in_space"),
            ".3f",
            "fraction of the sky",
            "predicted: boresights with the stars lost in space needs",
        ),
        _exclusion_line(getattr(sensor, "exclusion", None)),
        _given(mass_kg, "kg", "mass", "mass_kg"),
        _given(power_w, "W", "power", "power_w"),
    ]
    return {"sensor": sheet.get("sensor", sensor.name), "confidence": confidence, "lines": lines}
