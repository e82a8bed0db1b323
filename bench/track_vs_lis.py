"""Tracking against lost-in-space on the bench's ST-16 frame, robust to a loaded machine.

``bench/run.py track_frame_st16`` takes the best of 5 calls, which another job on the same cores
can still double. This times blocks of calls in one process, the blocks of lost in space
(``Solver(image)``) and of tracking (``track_frame(solver, image, prior)``) interleaved so that
neighbouring blocks see one load, and prints the minimum and the median per call over the
blocks, wall (``perf_counter``) and CPU (``process_time``), and the ratios: of the minima, of the
medians, and the median of the blocks' CPU ratios; with the background estimated ("auto") or
the sensor's known bias ("known"). A tracked frame computes its Rotation, (RA, Dec, roll),
covariance and match tables when first read: the first tracking line reads none of them, the
second all (the lost-in-space solution computes them all)::

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


def _block(fn, per_block: int) -> tuple[float, float]:
    """Wall and CPU seconds per call of ``per_block`` calls."""
    t, c = time.perf_counter(), time.process_time()
    for _ in range(per_block):
        fn()
    return (time.perf_counter() - t) / per_block, (time.process_time() - c) / per_block


def _interleaved(fns: dict, n_blocks: int, per_block: dict) -> dict:
    """Blocks of each function in turn: per function, (wall, CPU) seconds per call per block.

    Interleaved, every block of one sees the machine as the neighbouring blocks of the others
    do: the ratios of neighbouring blocks are those of one load.
    """
    out = {name: [] for name in fns}
    for _ in range(n_blocks):
        for name, fn in fns.items():
            out[name].append(_block(fn, per_block[name]))
    return {name: np.array(v) for name, v in out.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("background", nargs="?", default="known", choices=["auto", "known"])
    parser.add_argument("--blocks", type=int, default=40, help="blocks of each timing")
    args = parser.parse_args()
    sensor, cat, att, rate = st16_frame_inputs()
    image = render_frame(sensor, att, cat, rate_rad_s=rate, max_mag=5.75, rng=1).image
    # the bench's prior: 0.01 deg, the rate to 0.005 deg/s
    prior = Prior(att, np.eye(3) * np.radians(0.01) ** 2, rate, np.eye(3) * np.radians(0.005) ** 2)
    known = args.background == "known"
    solver = Solver(sensor, background=args.background, centroid_sigma_px="snr" if known else 0.3)
    lis, tracked = solver(image), track_frame(solver, image, prior)  # database and caches, once
    assert lis.solved and tracked.mode == "tracking" and tracked.solution.solved
    got = _interleaved(
        {
            "lost in space": lambda: solver(image),
            "tracking": lambda: track_frame(solver, image, prior),
            "tracking, every field read": lambda: _read_all(track_frame(solver, image, prior)),
        },
        args.blocks,
        {"lost in space": 2, "tracking": 20, "tracking, every field read": 20},
    )
    lis_t = got.pop("lost in space") * 1e3
    print(
        f"{args.background}: lost in space {lis_t[:, 0].min():.2f} ms min, "
        f"{np.median(lis_t[:, 0]):.2f} ms median (CPU {lis_t[:, 1].min():.2f} / "
        f"{np.median(lis_t[:, 1]):.2f}); {args.blocks} interleaved blocks"
    )
    for what, t in got.items():
        t = t * 1e3
        ratio = np.median(lis_t[:, 1] / t[:, 1])  # block by block, CPU
        print(
            f"  {what}: {t[:, 0].min():.3f} ms min, {np.median(t[:, 0]):.3f} ms median (CPU "
            f"{t[:, 1].min():.3f} / {np.median(t[:, 1]):.3f}); ratio "
            f"{lis_t[:, 0].min() / t[:, 0].min():.1f}x of minima, "
            f"{np.median(lis_t[:, 0]) / np.median(t[:, 0]):.1f}x of medians, "
            f"{ratio:.1f}x median of the blocks' CPU ratios"
        )


def _read_all(result) -> None:
    """Read what a tracked frame computes on first read (its solution's JSON fields and more)."""
    s = result.solution
    _ = s.rotation, s.ra_rad, s.dec_rad, s.roll_rad, s.sigma_rad, s.matches, s.centroids_px
    _ = result.covariance_rad2


if __name__ == "__main__":
    main()
