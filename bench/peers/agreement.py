"""Whole-frame figures of the peer comparison: time per stage, and agreement between solvers.

Plain functions on the per-frame records of ``compare.py`` (``{"solved", "ra_deg", "dec_deg",
"ms", ...}``); starsense's records carry ``stage_ms`` (detect_ms, identify_ms, attitude_ms,
database_ms), cedar-solve's ``t_extract_ms`` / ``t_solve_ms`` (its own T_extract / T_solve).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

ARCSEC = math.radians(1.0 / 3600.0)
_STAGES = ("extract_ms", "solve_ms", "ms")


def _vec(ra_deg: float, dec_deg: float) -> np.ndarray:
    ra, dec = math.radians(ra_deg), math.radians(dec_deg)
    return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])


def separation_arcsec(a: dict, b: dict) -> float:
    """Great-circle separation of two solved records' boresights, arcsec."""
    dot = float(_vec(a["ra_deg"], a["dec_deg"]) @ _vec(b["ra_deg"], b["dec_deg"]))
    return math.acos(min(max(dot, -1.0), 1.0)) / ARCSEC


def stage_split(starsense: list[dict], cedar: list[dict] | None) -> dict:
    """Mean time per stage over the frames, ms: extraction and solve, per solver."""

    def mean(records, key):
        values = [r[key] for r in records if r.get(key) is not None]
        return float(np.mean(values)) if values else None

    ours = [
        {
            "extract_ms": r["stage_ms"].get("detect_ms"),
            "solve_ms": r["stage_ms"].get("identify_ms", 0.0)
            + r["stage_ms"].get("attitude_ms", 0.0),
            "ms": r["ms"],
        }
        for r in starsense
    ]
    out = {"starsense": {k: mean(ours, k) for k in ("extract_ms", "solve_ms", "ms")}}
    if cedar is not None:
        theirs = [
            {"extract_ms": r.get("t_extract_ms"), "solve_ms": r.get("t_solve_ms"), "ms": r["ms"]}
            for r in cedar
        ]
        out["cedar"] = {k: mean(theirs, k) for k in ("extract_ms", "solve_ms", "ms")}
        s, c = out["starsense"], out["cedar"]
        out["ratio_starsense_over_cedar"] = {
            k: (s[k] / c[k] if s[k] and c[k] else None) for k in ("extract_ms", "solve_ms", "ms")
        }
    return out


def agreement(solvers: dict[str, list[dict]], reference: list[dict] | None = None) -> dict:
    """Per pair of solvers (and each against `reference`): boresight separations, arcsec.

    Parameters
    ----------
    solvers : dict
        Solver name -> per-frame records (the same frames, same order).
    reference : list of dict, optional
        Per-frame reference records (``ra_deg``, ``dec_deg``), e.g. reference.json.

    Returns
    -------
    dict
        ``"a vs b"`` -> {"n_both", "median_arcsec", "max_arcsec", "per_frame"}.
    """
    named = dict(solvers)
    if reference is not None:
        named["reference"] = [{**r, "solved": True} for r in reference]
    out = {}
    for a, b in itertools.combinations(named, 2):
        seps = [
            separation_arcsec(ra, rb) if ra["solved"] and rb["solved"] else None
            for ra, rb in zip(named[a], named[b], strict=True)
        ]
        both = [s for s in seps if s is not None]
        out[f"{a} vs {b}"] = {
            "n_both": len(both),
            "median_arcsec": float(np.median(both)) if both else None,
            "max_arcsec": float(np.max(both)) if both else None,
            "per_frame": seps,
        }
    return out


def print_stage_split(split: dict) -> None:
    """Print :func:`stage_split` as a small table."""
    print(
        f"{'whole frames, mean per frame':50s} {'extract ms':>11s} {'solve ms':>9s} {'all ms':>8s}"
    )
    for who in ("starsense", "cedar"):
        if who in split:
            r = split[who]
            cells = [
                f"{r[k]:.2f}" if r[k] is not None else "-" for k in ("extract_ms", "solve_ms", "ms")
            ]
            print(f"{'  ' + who:50s} {cells[0]:>11s} {cells[1]:>9s} {cells[2]:>8s}")
    if "ratio_starsense_over_cedar" in split:
        r = split["ratio_starsense_over_cedar"]
        cells = [
            f"{r[k]:.2f}x" if r[k] is not None else "-" for k in ("extract_ms", "solve_ms", "ms")
        ]
        print(f"{'  starsense / cedar':50s} {cells[0]:>11s} {cells[1]:>9s} {cells[2]:>8s}")


def print_agreement(title: str, table: dict, solvers: dict[str, list[dict]]) -> None:
    """Print :func:`agreement` and each solver's solved count and median time."""
    print(title)
    for who, records in solvers.items():
        solved = sum(r["solved"] for r in records)
        ms = float(np.median([r["ms"] for r in records])) if records else float("nan")
        print(f"  {who:20s} solved {solved}/{len(records)}, median {ms:.1f} ms per frame")
    for pair, r in table.items():
        if r["n_both"]:
            print(
                f"  {pair:30s} {r['n_both']} frames both solved: median "
                f"{r['median_arcsec']:.1f} arcsec, max {r['max_arcsec']:.1f} arcsec"
            )
        else:
            print(f"  {pair:30s} no frame solved by both")
