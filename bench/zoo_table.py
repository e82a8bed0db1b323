"""The sensor zoo's results as a Markdown table (for the README and the Performance page).

``python bench/zoo_table.py [bench/results/zoo.json]`` prints one row per design: its field,
pixel, PSF, bits and median stars in the field; at rest and at 1 deg/s the frames solved, the
wrong solutions and measured / predicted per axis (cross-boresight, roll), marked ``*`` when
outside 0.8-1.25, with its 95 % interval over the frames; the time and peak memory of its
datasheet. A summary line counts the designs in band, and those whose intervals reach the band
on both axes (a ratio out of band by the chance of its frames, not by a wrong model). Designs
whose fields hold fewer than 3 detectable stars have no ratio: the datasheet says they cannot
solve, and the table says so.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
BAND = (0.8, 1.25)


def _ratio(value, ci=None) -> str:
    if value is None:
        return "-"
    mark = "" if BAND[0] <= value <= BAND[1] else "*"
    band = "" if ci is None else f" ({ci[0]:.2f}-{ci[1]:.2f})"
    return f"{value:.2f}{mark}{band}"


def _run(mc: dict | None) -> list[str]:
    mc = mc or {}
    if not mc.get("frames"):
        return ["-", "-", "-", "-"]
    return [
        f"{mc.get('solved', 0)}/{mc['frames']}",
        str(mc.get("wrong", 0)),
        _ratio(mc.get("cross_ratio"), mc.get("cross_ratio_ci95")),
        _ratio(mc.get("roll_ratio"), mc.get("roll_ratio_ci95")),
    ]


def _both_in_band(mc: dict | None) -> bool | None:
    mc = mc or {}
    values = [mc.get("cross_ratio"), mc.get("roll_ratio")]
    if any(v is None for v in values):
        return None
    return all(BAND[0] <= v <= BAND[1] for v in values)


def _reaches_band(mc: dict | None) -> bool | None:
    """Whether both ratios' 95 % intervals reach 0.8-1.25 (None: no interval)."""
    mc = mc or {}
    cis = [mc.get("cross_ratio_ci95"), mc.get("roll_ratio_ci95")]
    if any(ci is None for ci in cis):
        return None
    return all(ci[0] <= BAND[1] and ci[1] >= BAND[0] for ci in cis)


def table(rows: list[dict]) -> str:
    """Return the Markdown table of the zoo's rows and its summary line."""
    head = (
        "| design | field deg | pixel um | PSF sigma px | bits | stars | rest solved | wrong "
        "| cross | roll | 1 deg/s solved | wrong | cross | roll | s | MB |"
    )
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        if "error" in r or "skipped" in r:
            why = f"failed: {r['error']}" if "error" in r else f"no Monte Carlo: {r['skipped']}"
            lines.append(f"| {r['design']} | {why} |" + " |" * 14)
            continue
        p = r["params"]
        fov = p.get("fov_deg")
        if fov is None:  # a design given by its focal length
            half = 0.5 * p["columns"] * p["pitch_um"] * 1e-6
            fov = 2 * math.degrees(math.atan(half / p["focal_length_m"]))
        cells = [
            r["design"],
            f"{fov:.1f}",
            f"{p['pitch_um']:.1f}",
            f"{p['psf_sigma_px']:.2f}",
            str(p["bit_depth"]),
            f"{r.get('stars_in_fov', 0):.0f}",
            *_run(r.get("monte_carlo")),
            *_run(r.get("monte_carlo_at_rate")),
            f"{r['seconds']:.0f}",
            f"{r['peak_mb']:.0f}",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append(summary_line(rows))
    return "\n".join(lines)


def summary_line(rows: list[dict]) -> str:
    """Return the counts: designs, with ratios, in band at rest and at rate, wrong, peak memory."""
    ok = [r for r in rows if "error" not in r and "skipped" not in r]
    rest = [_both_in_band(r.get("monte_carlo")) for r in ok]
    rate = [_both_in_band(r.get("monte_carlo_at_rate")) for r in ok]
    wrong = sum(
        (r.get(k) or {}).get("wrong") or 0
        for r in ok
        for k in ("monte_carlo", "monte_carlo_at_rate")
    )
    frames = sum(
        (r.get(k) or {}).get("frames") or 0
        for r in ok
        for k in ("monte_carlo", "monte_carlo_at_rate")
    )
    peak = max((r["peak_mb"] for r in ok), default=0.0)
    rest_n = sum(v is not None for v in rest)
    rate_n = sum(v is not None for v in rate)
    line = (
        f"{len(rows)} designs; in 0.8-1.25 on both axes: at rest {sum(bool(v) for v in rest)} of "
        f"{rest_n} with ratios, at 1 deg/s {sum(bool(v) for v in rate)} of {rate_n}; "
        f"{wrong} wrong in {frames} frames; peak memory {peak:.0f} MB"
    )
    reach = [[_reaches_band(r.get(k)) for r in ok] for k in ("monte_carlo", "monte_carlo_at_rate")]
    if any(v is not None for v in reach[0] + reach[1]):
        line += (
            "; 95 % intervals reaching 0.8-1.25 on both axes: at rest "
            f"{sum(bool(v) for v in reach[0])} of {sum(v is not None for v in reach[0])}, "
            f"at 1 deg/s {sum(bool(v) for v in reach[1])} of {sum(v is not None for v in reach[1])}"
        )
    return line


def main(argv: list[str]) -> int:
    path = Path(argv[0]) if argv else RESULTS / "zoo.json"
    try:
        rows = json.loads(path.read_text())["rows"]
    except (OSError, ValueError, KeyError) as exc:
        print(f"zoo_table: cannot read {path}: {exc}", file=sys.stderr)
        return 2
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
