"""The fast read-out against the reference one on the ST-16 datasheet's Monte Carlo.

Builds the datasheet's Monte Carlo check twice from the same seed (the same attitudes, so the
same prediction): frames read out by :func:`starsense.render.readout.fast_read_out` (what the
datasheet uses) and by :func:`starsense.render.noise.apply_noise`, and prints the measured /
predicted ratios of both with their Monte Carlo standard error (delta method on the per-frame
squared errors), and the CPU time per frame of each run. Run::

    PYTHONPATH=src .venv/bin/python bench/readout_check.py [--frames 1000] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

import starsense.analysis.datasheet.sheet as sheet
from starsense.analysis.datasheet import DatasheetSettings, build_datasheet
from starsense.analysis.montecarlo import montecarlo
from starsense.catalog import load_catalog
from starsense.scale import dask_client
from starsense.sensor import load_sensor


def _run(sensor, cat, frames: int, fast: bool, client) -> tuple[dict, float, list]:
    """The datasheet's Monte Carlo check with one read-out; its wall time; the runs."""
    runs = []

    def recorded(*args, **kw):
        res = montecarlo(*args, **kw, fast_noise=fast)
        runs.append(res)
        return res

    sheet.montecarlo = recorded  # the datasheet's own run, with this read-out
    settings = DatasheetSettings(n_trials=frames, n_rate_trials=0, seed=11)
    t0 = time.perf_counter()
    d = build_datasheet(sensor, cat, settings=settings, client=client).to_dict()
    return d["monte_carlo"], time.perf_counter() - t0, runs


def _se(res, ratio: float, axis: str) -> float:
    """Monte Carlo standard error of a ratio sqrt(mean(a) / P): ratio x SE(mean a) / 2 mean a."""
    e = res.errors_rad
    a = 0.5 * (e[:, 0] ** 2 + e[:, 1] ** 2) if axis == "cross" else e[:, 2] ** 2
    return ratio * float(a.std(ddof=1) / math.sqrt(len(a))) / (2 * float(a.mean()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    sensor, cat = load_sensor("st16"), load_catalog("hipparcos")
    out = {}
    with dask_client(f"local:{args.workers}") as client:
        for fast in (True, False):
            mc, wall, runs = _run(sensor, cat, args.frames, fast, client)
            res = runs[0]
            key = "fast" if fast else "reference"
            out[key] = {
                "wall_s": wall,
                "render_ms": res.time_ms["render"],
                "solve_ms": res.time_ms["solve"],
                **{k: mc[k] for k in ("solved", "wrong", "cross_ratio", "roll_ratio")},
                **{k: mc[k] for k in ("cross_ratio_robust", "roll_ratio_robust")},
                "cross_ratio_se": _se(res, mc["cross_ratio"], "cross"),
                "roll_ratio_se": _se(res, mc["roll_ratio"], "roll"),
                "stars_matched_mean": float(np.mean(res.n_matched)),
            }
            print(key, json.dumps(out[key]), flush=True)
    for axis in ("cross", "roll"):
        a, b = out["fast"], out["reference"]
        diff = a[f"{axis}_ratio"] - b[f"{axis}_ratio"]
        se = math.hypot(a[f"{axis}_ratio_se"], b[f"{axis}_ratio_se"])
        print(f"{axis}: fast - reference = {diff:+.4f} ({diff / se:+.2f} standard errors)")


if __name__ == "__main__":
    main()
