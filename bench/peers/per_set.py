"""starsense beside astrometry.net on every real frame set of the shared data, set by set.

    python bench/peers/per_set.py [--sets NAME ...] [--cpulimit S] [--no-astrometry]

Part of ``make bench-peers`` (``compare.py`` calls :func:`astrometry_sets` and :func:`table`);
run alone it solves only the real frame sets and writes ``bench/results/peer_sets.json``. Every
folder of ``../shared/data/images`` with a reference.json is a set (``frame_sets.py`` reads it).

Same frames for both solvers. starsense is told nothing (the field found by its own scale
search), one thread, in-process: the time is one ``Solver()(image)`` call after an untimed call
on the same frame (database build or load). astrometry.net is ``solve-field`` on the frame's file
(``run_astrometry.py``), its field searched within +-20 % of the camera's nominal field where the
set states one (unconstrained otherwise), bounded by ``--cpulimit`` CPU seconds a frame: the time
is the wall time of the whole process (start, index loading, its own source extraction). A frame
that does not solve counts its time too; medians are over every frame of the set. The time ratio
is astrometry.net's median over starsense's, over every frame and over the frames both solved
correctly (per-frame ratios' median). astrometry.net is optional: when ``solve-field`` is missing
its columns say "not run" and why.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE.parent))
import frame_sets  # noqa: E402
import run_astrometry  # noqa: E402
from run import RESULTS, machine  # noqa: E402

from starsense._io import atomic_write  # noqa: E402

IMAGES = ROOT.parent / "shared" / "data" / "images"
#: solve-field's CPU limit per frame, s (the openstartracker references were made with 150 s)
CPULIMIT_S = 60


def load_sets(names, images: Path = IMAGES) -> dict:
    """The sets named (default: every set found), in order; absent ones said and skipped."""
    sets = {}
    for name in frame_sets.discover(images) if names is None else names:
        folder = images / name
        if (folder / "reference.json").is_file():
            sets[name] = frame_sets.load_set(folder)
        else:
            print(f"frame set {name}: {folder}/reference.json not found, skipped")
    return sets


def astrometry_sets(sets: dict, cpulimit_s: int = CPULIMIT_S) -> tuple[dict | None, str]:
    """solve-field on every frame of every set: ({set: records}, version) or (None, why not)."""
    ok, what = run_astrometry.available()
    if not ok:
        return None, what
    out = {}
    for key, fs in sets.items():
        print(f"astrometry.net on {key}/ ({len(fs['names'])} frames) ...", flush=True)
        out[key] = [
            run_astrometry.solve(fs["folder"] / n, fs["fov_deg"], cpulimit_s) for n in fs["names"]
        ]
    return out, what


def _correct(rec: dict, ref: dict | None, tol: float) -> bool:
    if ref is None or not rec.get("solved"):
        return False
    return frame_sets._separation_arcsec(rec, ref) <= tol


def compare_set(fs: dict, ours: list[dict], theirs: list[dict] | None) -> dict:
    """One set's row: starsense's and astrometry.net's scores and the time ratios."""
    row = {
        "frames": len(fs["names"]),
        "n_reference": sum(r is not None for r in fs["references"]),
        "tolerance_arcsec": fs["tolerance_arcsec"],
        "tolerance_stated": fs["tolerance_stated"],
        "camera_fov_deg": fs["fov_deg"],
        "starsense": frame_sets.score_set(ours, fs),
        "starsense_ms": [r["ms"] for r in ours],
    }
    if theirs is None:
        return row
    row["astrometry.net"] = frame_sets.score_set(theirs, fs)
    row["astrometry_ms"] = [r["ms"] for r in theirs]
    ours_median = row["starsense"]["median_ms"]
    theirs_median = row["astrometry.net"]["median_ms"]
    row["ratio_median_all"] = theirs_median / ours_median if ours_median else None
    tol = fs["tolerance_arcsec"]
    both = [
        t["ms"] / o["ms"]
        for o, t, ref in zip(ours, theirs, fs["references"], strict=True)
        if _correct(o, ref, tol) and _correct(t, ref, tol)
    ]
    row["n_both_correct"] = len(both)
    row["ratio_median_both_correct"] = float(np.median(both)) if both else None
    return row


def _solved(score: dict) -> str:
    text = f"{score['solved']}/{score['n_reference']}"
    if score["claimed_without_reference"]:
        text += f" (+{score['claimed_without_reference']} w/o ref.)"
    return text


def _fmt(value, spec: str) -> str:
    return "-" if value is None or value != value else format(value, spec)


def table(rows: dict, astro_why: str, astro_ok: bool, cpulimit_s: int) -> str:
    """The per-set table, Markdown, with the conditions of both solvers said beneath it."""
    lines = [
        "| set | frames (with reference) | tolerance | starsense solved | wrong | median ms "
        "| astrometry.net solved | wrong | median s | time ratio: all frames "
        "| time ratio: both correct |",
        "|---" * 11 + "|",
    ]
    for key, r in rows.items():
        ours = r["starsense"]
        tol = f'{r["tolerance_arcsec"]:.0f}"'
        if not r["tolerance_stated"]:
            tol += " (default)"
        cells = [
            f"{key}/",
            f"{r['frames']} ({r['n_reference']})",
            tol,
            _solved(ours),
            str(ours["wrong"]),
            _fmt(ours["median_ms"], ".3g"),
        ]
        theirs = r.get("astrometry.net")
        if theirs is None:
            cells += ["not run"] * 5
        else:
            median_s = None if theirs["median_ms"] is None else theirs["median_ms"] / 1e3
            both = _fmt(r["ratio_median_both_correct"], ".0f")
            cells += [
                _solved(theirs),
                str(theirs["wrong"]),
                _fmt(median_s, ".3g"),
                _fmt(r["ratio_median_all"], ".0f"),
                f"{both} ({r['n_both_correct']} frames)",
            ]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append(
        "\nstarsense: field unknown, one thread, one in-process call after a warm-up call. "
        + (
            f"astrometry.net ({astro_why}, Tycho-2 index 10-19): solve-field's whole process "
            f"wall time, --cpulimit {cpulimit_s} s a frame, field within +-20 % of the camera's "
            "where the set states one. Medians over every frame; ratio = astrometry.net's "
            "time over starsense's."
            if astro_ok
            else f"astrometry.net not run: {astro_why}"
        )
    )
    return "\n".join(lines)


def per_set(sets: dict, ours: dict, astro: dict | None) -> dict:
    """Every set's row (:func:`compare_set`)."""
    return {
        key: compare_set(fs, ours[key], None if astro is None else astro[key])
        for key, fs in sets.items()
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", nargs="*", help="frame sets of the shared data (default: all)")
    parser.add_argument("--cpulimit", type=int, default=CPULIMIT_S, help="solve-field, s/frame")
    parser.add_argument("--no-astrometry", action="store_true", help="skip solve-field")
    parser.add_argument("--out", type=Path, default=RESULTS / "peer_sets.json")
    args = parser.parse_args(argv)
    sets = load_sets(args.sets)
    if not sets:
        print(f"no frame set found under {IMAGES}")
        return 1
    ours = {}
    for key, fs in sets.items():
        print(f"starsense on {key}/ ({len(fs['names'])} frames) ...", flush=True)
        ours[key] = frame_sets.starsense_set(fs)
    astro, why = None, "skipped (--no-astrometry)"
    if not args.no_astrometry:
        astro, why = astrometry_sets(sets, args.cpulimit)
    rows = per_set(sets, ours, astro)
    text = table(rows, why, astro is not None, args.cpulimit)
    print("\nper set, starsense beside astrometry.net:\n" + text)
    record = {
        "name": "peer_sets",
        "description": "starsense and astrometry.net on every real frame set (per_set.py)",
        "sets": rows,
        "frame_names": {key: fs["names"] for key, fs in sets.items()},
        "starsense_records": ours,
        "astrometry_records": astro,
        "astrometry": why,
        "cpulimit_s": args.cpulimit,
        "table_markdown": text,
        "load_average": list(os.getloadavg()),
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(args.out) as f:
        json.dump(record, f, indent=2)
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
