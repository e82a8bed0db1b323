"""Tracking against lost-in-space on the bench's ST-16 frame, robust to a loaded machine.

``bench/run.py track_frame_st16`` takes the best of 5 calls, which another job on the same cores
can still double. This times blocks of calls in one process and prints the minimum and the
median per call over the blocks, wall (``perf_counter``) and CPU (``process_time``), for
``track_frame(solver, image, prior)`` and ``Solver(image)``, with the background estimated
("auto") or the sensor's known bias ("known"). A tracked frame computes its Rotation, (RA, Dec,
roll), covariance and tables when first read; the second tracking line reads them all (as the
lost-in-space solution has them), the first only what a tracking loop needs (the attitude
matrix, the status and the rate)::

    PYTHONPATH=src .venv/bin/python bench/track_vs_lis.py [auto|known] [--blocks 40]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from run import st16_frame_inputs  # noqa: E402

from starsense.render.scene import render_frame  # noqa: E402
from starsense.solve.solver import Solver  # noqa: E402
from starsense.solve.tracking import Prior, track_frame  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _blocks(fn, n_blocks: int, per_block: int) -> tuple[float, float, float, float]:
    """Minimum and median seconds per call over blocks: wall, then CPU."""
    wall, cpu = [], []
    for _ in range(n_blocks):
        t, c = time.perf_counter(), time.process_time()
        for _ in range(per_block):
            fn()
        wall.append((time.perf_counter() - t) / per_block)
        cpu.append((time.process_time() - c) / per_block)
    return float(np.min(wall)), float(np.median(wall)), float(np.min(cpu)), float(np.median(cpu))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("background", nargs="?", default="known", choices=["auto", "known"])
    parser.add_argument("--blocks", type=int, default=40, help="blocks of 10 tracks")
    args = parser.parse_args()
    sensor, cat, att, rate = st16_frame_inputs()
    image = render_frame(sensor, att, cat, rate_rad_s=rate, max_mag=5.75, rng=1).image
    # the bench's prior: 0.01 deg, the rate to 0.005 deg/s
    prior = Prior(att, np.eye(3) * np.radians(0.01) ** 2, rate, np.eye(3) * np.radians(0.005) ** 2)
    known = args.background == "known"
    solver = Solver(sensor, background=args.background, centroid_sigma_px="snr" if known else 0.3)
    lis, tracked = solver(image), track_frame(solver, image, prior)  # database and caches, once
    assert lis.solved and tracked.mode == "tracking" and tracked.solution.solved
    track = _blocks(lambda: track_frame(solver, image, prior), args.blocks, 10)
    read = _blocks(lambda: _read_all(track_frame(solver, image, prior)), args.blocks, 10)
    solve = _blocks(lambda: solver(image), max(args.blocks // 3, 3), 2 if known else 1)
    s_ms = [v * 1e3 for v in solve]
    print(
        f"{args.background}: lost-in-space {s_ms[0]:.1f} ms min, {s_ms[1]:.1f} ms median (CPU "
        f"{s_ms[2]:.1f} / {s_ms[3]:.1f})"
    )
    for what, times in (("tracking", track), ("tracking, every field read", read)):
        t_ms = [v * 1e3 for v in times]
        print(
            f"  {what}: {t_ms[0]:.3f} ms min, {t_ms[1]:.3f} ms median (CPU {t_ms[2]:.3f} / "
            f"{t_ms[3]:.3f}); ratio {s_ms[0] / t_ms[0]:.1f}x of minima, "
            f"{s_ms[1] / t_ms[1]:.1f}x of medians, {s_ms[3] / t_ms[3]:.1f}x of CPU medians"
        )


def _read_all(result) -> None:
    """Read what a tracked frame computes on first read (its solution's JSON fields and more)."""
    s = result.solution
    _ = s.rotation, s.ra_rad, s.dec_rad, s.roll_rad, s.sigma_rad, s.matches, s.centroids_px
    _ = result.covariance_rad2


if __name__ == "__main__":
    main()
