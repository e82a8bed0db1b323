"""Lost-in-space speed of starsense alone, on the peer comparison's synthetic centroid sets.

The inputs and the call are those of ``bench/peers/compare.py`` (its ``SYNTH_SETS``: 2,001
Fibonacci boresights, 15 deg across 1280 x 960, the standard set and the hard one), the
identifier ``HashIdentifier(build_database(hipparcos, 15 deg))`` fed through
``pinhole_vectors``; no peer runs. Time per solve is CPU time (``time.process_time``), which a
machine shared with other jobs disturbs less than wall time (``--wall``: wall time, as
compare.py times). Wrong: boresight more than 1 arcmin from the truth. ``--reference`` forces
the NumPy form of the search (``HashIdentifier(..., compiled=False)``), ``--profile`` prints
the cProfile of the standard set.

    .venv/bin/python bench/lis_speed.py [-n 2001] [--passes 3] [--wall] [--reference] [--profile]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
from compare import SYNTH_FOV_DEG, SYNTH_SETS, SYNTH_SIZE, synthetic_inputs  # noqa: E402

from starsense.catalog import load_catalog  # noqa: E402
from starsense.identify import HashIdentifier, build_database  # noqa: E402
from starsense.solve.pinhole import pinhole_vectors  # noqa: E402

ARCMIN = math.radians(1.0 / 60.0)


def run_set(identify, xy, offsets, bores, fov, clock=time.process_time):
    """Solve every set; return (solved, wrong, ms per solve on `clock`)."""
    ms, solved, wrong = [], 0, 0
    for i in range(len(offsets) - 1):
        pts = xy[offsets[i] : offsets[i + 1]]
        t0 = clock()
        ident = identify(pinhole_vectors(pts[:, 0], pts[:, 1], shape=SYNTH_SIZE, fov_rad=fov), fov)
        ms.append((clock() - t0) * 1e3)
        if ident.solved:
            solved += 1
            b = ident.rotation.inv().apply([0.0, 0.0, 1.0])
            wrong += math.acos(min(1.0, float(b @ bores[i]))) > ARCMIN
    return solved, wrong, np.asarray(ms)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=2001)
    parser.add_argument("--reference", action="store_true", help="the NumPy kernels only")
    parser.add_argument("--profile", action="store_true", help="cProfile the standard set")
    parser.add_argument("--passes", type=int, default=3, help="timed passes over each set")
    parser.add_argument("--wall", action="store_true", help="wall time, as compare.py times")
    args = parser.parse_args(argv)
    fov = math.radians(SYNTH_FOV_DEG)
    db = build_database(load_catalog("hipparcos"), fov)
    identify = HashIdentifier(db, compiled=not args.reference)
    clock, kind = (time.perf_counter, "wall") if args.wall else (time.process_time, "CPU")
    for key, (label, kw) in SYNTH_SETS.items():
        xy, offsets, bores = synthetic_inputs(args.n, **kw)
        run_set(identify, xy, offsets[:21], bores, fov)  # warm-up
        if args.profile and key == "synthetic":
            import cProfile
            import pstats

            prof = cProfile.Profile()
            prof.enable()
            run_set(identify, xy, offsets, bores, fov)
            prof.disable()
            pstats.Stats(prof).sort_stats("tottime").print_stats(25)
        for _ in range(args.passes):  # a shared machine: the passes show the spread
            solved, wrong, ms = run_set(identify, xy, offsets, bores, fov, clock)
            n = len(offsets) - 1
            print(
                f"{label:50s} solved {solved}/{n} wrong {wrong} {kind} ms: median "
                f"{np.median(ms):.3f} mean {ms.mean():.3f} p99 {np.percentile(ms, 99):.3f}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
