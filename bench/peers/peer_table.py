"""Scores and the side-by-side table of the peer comparison (``bench/peers/compare.py``).

Plain functions on per-case records ``{"solved", "ra_deg", "dec_deg", "ms", ...}``: one score
per (input, solver), and the table of every solver on every input that ``make bench-peers``
prints (Markdown, so the README quotes it as printed).
"""

from __future__ import annotations

import math

import numpy as np

ARCSEC = math.radians(1.0 / 3600.0)
SOLVERS = ("starsense", "cedar", "tetra3rs", "astrometry.net")
LABELS = {"cedar": "cedar-solve"}


def _vec(ra_deg, dec_deg):
    ra, dec = math.radians(ra_deg), math.radians(dec_deg)
    return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])


def score(records, truth_vectors, limit_rad) -> dict:
    """Solved, wrong (boresight beyond `limit_rad` of the truth) and times of one solver."""
    n = len(records)
    errors = [
        math.acos(min(1.0, max(-1.0, float(_vec(r["ra_deg"], r["dec_deg"]) @ t))))
        for r, t in zip(records, truth_vectors, strict=True)
        if r["solved"]
    ]
    wrong = sum(e > limit_rad for e in errors)
    ms = np.array([r["ms"] for r in records])
    return {
        "n": n,
        "solved": len(errors),
        "wrong": int(wrong),
        "solve_rate": len(errors) / n,
        "wrong_rate": wrong / n,
        "correct_rate": (len(errors) - wrong) / n,
        "mean_ms": float(ms.mean()),
        "median_ms": float(np.median(ms)),
        "p99_ms": float(np.percentile(ms, 99)),
        "max_ms": float(ms.max()),
        "median_error_arcsec": float(np.median(errors) / ARCSEC) if errors else None,
    }


def print_scores(label: str, entry: dict) -> None:
    """One line per solver of one input (solved, wrong, mean, median, p99 and worst ms, error)."""
    for who in SOLVERS:
        if who not in entry:
            continue
        r = entry[who]
        err = "-" if r["median_error_arcsec"] is None else f"{r['median_error_arcsec']:.1f}"
        print(
            f"{label:50s} {LABELS.get(who, who):14s} {r['solved']:>4d}/{r['n']:<4d}"
            f"{r['wrong']:>5d} {r['mean_ms']:9.2f} {r['median_ms']:10.3f} {r['p99_ms']:8.3f}"
            f" {r['max_ms']:9.2f} {err:>7s}"
        )


def _cell(r: dict | None, mean: bool = False) -> str:
    if r is None:
        return "-"
    n = r.get("n_reference", r["n"])
    ms = r["mean_ms"] if mean else r["median_ms"]
    time = "-" if ms is None else f"{ms:.3g} ms"
    text = f"{r['solved']}/{n}, {r['wrong']} wrong, {'mean' if mean else 'median'} {time}"
    if not mean and r.get("p99_ms") is not None:  # the tail: what a flight loop budgets
        text += f", p99 {r['p99_ms']:.3g} ms, worst {r['max_ms']:.3g} ms"
    if r.get("claimed_without_reference"):
        text += f" (+{r['claimed_without_reference']} claimed without reference)"
    return text


def table(rows: list[tuple[str, dict, bool]], missing: dict[str, str]) -> str:
    """The side-by-side table, Markdown: one row per input, one column per solver.

    Parameters
    ----------
    rows : list of (label, {solver: score}, mean)
        Each input's scores (:func:`score` or ``frame_sets.score_set``); `mean` reports the
        mean time instead of the median.
    missing : dict
        Solver -> why it did not run; its column says "not run" and the reason follows.
    """
    head = "| input | " + " | ".join(LABELS.get(w, w) for w in SOLVERS) + " |"
    lines = [head, "|---" * (len(SOLVERS) + 1) + "|"]
    for label, scores, mean in rows:
        cells = ["not run" if who in missing else _cell(scores.get(who), mean) for who in SOLVERS]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    for who, why in missing.items():
        lines.append(f"\n{LABELS.get(who, who)} not run: {why}")
    return "\n".join(lines)
