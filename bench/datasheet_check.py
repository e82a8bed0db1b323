"""The datasheet's acceptance check: measured / predicted over >= 1,000 rendered frames.

For each sensor, the datasheet is built with 1,000 frames at rest (100 at the datasheet's rate)
on a local Dask cluster of all cores (the same results as in-process for the same seed), and
the Monte Carlo part is recorded in ``bench/results/datasheet_check_<sensor>.json``:
measured / predicted rms per axis (target 0.8-1.25), the robust ratios, wrong identifications
(target 0), roll / cross against the geometry. Run: ``python bench/datasheet_check.py
[--frames N] [SENSOR ...]`` (``make bench`` runs it).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from starsense._io import atomic_write
from starsense.analysis.datasheet import DatasheetSettings, build_datasheet
from starsense.catalog import load_catalog
from starsense.scale import dask_client
from starsense.sensor import load_sensor

RESULTS = Path(__file__).resolve().parent / "results"


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sensors", nargs="*", default=["st16", "esa_blackfly"])
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args(argv)
    cat = load_catalog("hipparcos")
    RESULTS.mkdir(parents=True, exist_ok=True)
    ok = True
    with dask_client(f"local:{os.cpu_count() or 1}") as client:
        for name in args.sensors:
            t0 = time.perf_counter()
            settings = DatasheetSettings(n_trials=args.frames, n_rate_trials=100, seed=args.seed)
            d = build_datasheet(load_sensor(name), cat, settings=settings, client=client).to_dict()
            mc = d["monte_carlo"]
            record = {
                "sensor": name,
                "frames": mc["frames"],
                "seconds": time.perf_counter() - t0,
                "monte_carlo": mc,
                "nea_arcsec": d["nea_arcsec"],
                "roll_over_cross": d["roll_over_cross"],
                "limit_arcsec": d["limit_arcsec"],
                "date": time.strftime("%Y-%m-%d"),
            }
            with atomic_write(RESULTS / f"datasheet_check_{name}.json") as f:
                json.dump(record, f, indent=2)
            good = mc["wrong"] == 0 and all(
                mc[k] is not None and 0.8 <= mc[k] <= 1.25 for k in ("cross_ratio", "roll_ratio")
            )
            ok &= good
            print(
                f"{name:14s} {mc['solved']}/{mc['frames']} solved, {mc['wrong']} wrong; "
                f"measured/predicted cross {mc['cross_ratio']:.3f} roll {mc['roll_ratio']:.3f} "
                f"(robust {mc['cross_ratio_robust']:.3f} / {mc['roll_ratio_robust']:.3f}, "
                f"{mc['outliers_5sigma']} beyond 5 sigma); roll/cross "
                f"{d['roll_over_cross']['nea']:.2f} "
                f"(geometry {d['roll_over_cross']['geometry']:.2f})"
                f"  {'ok' if good else 'OUT OF TARGET'}",
                flush=True,
            )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
