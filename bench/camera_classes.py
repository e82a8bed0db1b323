"""The solver judged over seeded camera classes, the field unknown: solved where evident, wrong.

Two classes (tests/_support): the faint, zero-clipped, cluttered 8-bit narrow camera
(``camera_class.class_frame``) and the wide undersampled imager (``wide_class.wide_frame``).
A frame is "evident" when the truth puts enough catalogue stars above a matched-filter SNR
(each module's docstring: the evidence an astrometry.net-class blind solver needs); a solution
is wrong when its boresight is more than 2 px off the truth or its roll moves the frame's
corner by more than 2 px. Results to bench/results/camera_classes.json.

    python bench/camera_classes.py --faint 120 --wide 100 --start 1000
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "_support"))

from camera_class import class_frame, luminance  # noqa: E402
from wide_class import wide_frame  # noqa: E402

from starsense.catalog import load_catalog  # noqa: E402
from starsense.geometry.attitude import small_rotation_angles  # noqa: E402
from starsense.solve.solver import Solver  # noqa: E402


def _wrong(frame, sol, image) -> bool:
    err = np.abs(small_rotation_angles(frame.attitude, sol.rotation))
    rows, cols = image.shape[:2]
    pixel = frame.fov_rad / cols
    corner = math.hypot(rows, cols) / 2.0
    return bool(max(err[:2]) > 2 * pixel or err[2] * corner > 2.0)


def run(kind: str, seeds, catalog, solver) -> dict:
    """Solve each seed's frame of one class; return its tallies and per-frame records."""
    records = []
    for seed in seeds:
        frame = class_frame(seed, catalog) if kind == "faint8" else wide_frame(seed, catalog)
        image = luminance(frame.image) if kind == "faint8" else frame.image
        t0 = time.perf_counter()
        sol = solver(image)
        ms = (time.perf_counter() - t0) * 1e3
        wrong = bool(sol.solved and _wrong(frame, sol, image))
        records.append(
            {"seed": seed, "evident": frame.evident, "n_evident": frame.n_evident,
             "status": sol.status, "wrong": wrong, "ms": ms, "notes": list(sol.notes)}
        )  # fmt: skip
        print(f"{kind} {seed} evident={frame.evident} {sol.status} wrong={wrong} {ms:.0f} ms",
              flush=True)  # fmt: skip
    evident = [r for r in records if r["evident"]]
    right = [r for r in evident if r["status"] == "solved" and not r["wrong"]]
    return {
        "frames": len(records),
        "evident": len(evident),
        "solved_evident": len(right),
        "solved_evident_fraction": len(right) / len(evident) if evident else None,
        "solved_any": sum(r["status"] == "solved" and not r["wrong"] for r in records),
        "wrong": sum(r["wrong"] for r in records),
        "median_ms": float(np.median([r["ms"] for r in records])),
        "near_miss_solved": sum(any("near miss" in n for n in r["notes"]) for r in records),
        "spikes_kept": sum(any("spikes kept" in n for n in r["notes"]) for r in records),
        "records": records,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--faint", type=int, default=120, help="frames of the faint 8-bit class")
    ap.add_argument("--wide", type=int, default=100, help="frames of the wide undersampled one")
    ap.add_argument("--start", type=int, default=1000, help="first seed (held out: >= 1000)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "camera_classes.json")
    a = ap.parse_args(argv)
    catalog = load_catalog("hipparcos")
    solver = Solver()
    print(f"seeds {a.start}-{a.start + max(a.faint, a.wide) - 1}", flush=True)
    out = {
        "name": "camera_classes",
        "description": __doc__.splitlines()[0],
        "start_seed": a.start,
        "faint8": run("faint8", range(a.start, a.start + a.faint), catalog, solver),
        "wide_undersampled": run("wide", range(a.start, a.start + a.wide), catalog, solver),
    }
    for key in ("faint8", "wide_undersampled"):
        r = out[key]
        print(f"{key}: {r['solved_evident']}/{r['evident']} evident solved, "
              f"{r['solved_any']}/{r['frames']} solved right, {r['wrong']} wrong, "
              f"median {r['median_ms']:.0f} ms, near misses solved {r['near_miss_solved']}, "
              f"spikes kept {r['spikes_kept']}")  # fmt: skip
    a.out.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
