"""A narrow field in bounded memory: ``starsense solve --sensor lin2024`` as a process.

Needs GNU ``/usr/bin/time`` (Debian package ``time``) for the child's peak memory.

Renders lin2024 frames (1.14 deg, 2048 x 2048, 2 arcsec pixels) from the bundled Gaia to
G = 10 at seeded pointings, then runs ``starsense solve FRAME --sensor lin2024 --json`` as a
child process twice per frame set: cold (an empty cache directory: the identification database
is built first) and warm (the database memory-mapped from the cache). For each it reports wall
time, the child's peak resident memory (``getrusage(RUSAGE_CHILDREN).ru_maxrss``, one child
at a time), the database's size on disk, and the boresight error against the rendered truth.

    .venv/bin/python bench/narrow_field.py [--frames 3]

Run it under an address-space limit on a shared machine (``prlimit --as=6000000000``).
Results: ``bench/results/narrow_field.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import RESULTS, machine

from starsense._io import atomic_write
from starsense.catalog import load_catalog
from starsense.geometry.attitude import angular_separation, attitude_from_radec_roll
from starsense.render.io import write_frame
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor

STARSENSE = Path(sys.executable).with_name("starsense")


def _child(cmd: list[str], env: dict) -> tuple[list, float, float, str]:
    """(one JSON object per frame, wall s, peak RSS MB of this child, its stderr).

    The peak is GNU time's ``%M`` of the child alone (``ru_maxrss`` of RUSAGE_CHILDREN is the
    largest of every child so far, so it cannot tell a warm run from the cold one before it).
    """
    t0 = time.perf_counter()
    run = subprocess.run(
        ["/usr/bin/time", "-f", "PEAK_KB %M", *cmd], capture_output=True, text=True, env=env
    )
    wall = time.perf_counter() - t0
    lines = run.stderr.strip().splitlines()
    peak = [ln for ln in lines if ln.startswith("PEAK_KB ")]
    if run.returncode not in (0, 1) or not peak:
        raise SystemExit(f"{' '.join(cmd)} exited {run.returncode}: {run.stderr.strip()}")
    stderr = "\n".join(ln for ln in lines if not ln.startswith("PEAK_KB "))
    try:  # one frame: one JSON object; a batch: one per line
        rows = [json.loads(run.stdout)]
    except json.JSONDecodeError:
        rows = [json.loads(line) for line in run.stdout.splitlines() if line.strip()]
    return rows, wall, int(peak[-1].split()[1]) / 1024.0, stderr


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=3)
    args = parser.parse_args(argv)
    sensor = load_sensor("lin2024")
    gaia = load_catalog("gaia")
    rng = np.random.default_rng(2024)
    out = {"name": "narrow_field", "machine": machine(), "date": time.strftime("%Y-%m-%d")}
    with tempfile.TemporaryDirectory(prefix="starsense-narrow-") as tmp:
        frames, truths = [], []
        for i in range(args.frames):
            ra, dec, roll = rng.uniform(0, 360), math.degrees(math.asin(rng.uniform(-1, 1))), 0.0
            truth = attitude_from_radec_roll(*(math.radians(a) for a in (ra, dec, roll)))
            frame = render_frame(sensor, truth, gaia, band="G", max_mag=10.0, rng=i)
            frames.append(str(write_frame(Path(tmp) / f"lin2024_{i}.tiff", frame)))
            truths.append(truth.inv().apply([0.0, 0.0, 1.0]))
        cache = Path(tmp) / "cache"
        env = {**os.environ, "STARSENSE_CACHE_DIR": str(cache)}
        runs = {}
        for mode in ("cold", "warm"):
            cmd = [str(STARSENSE), "solve", *frames, "--sensor", "lin2024", "--json"]
            result, wall, peak_mb, stderr = _child(cmd, env)
            sols = result
            errors = []
            for sol, truth in zip(sols, truths, strict=True):
                if sol.get("status") == "solved":
                    ra, dec = math.radians(sol["ra_deg"]), math.radians(sol["dec_deg"])
                    v = [math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)]
                    errors.append(float(angular_separation(np.array(v), truth)) * 206264.8)
            db_bytes = sum(f.stat().st_size for f in cache.rglob("iddb-*/*"))
            runs[mode] = {
                "wall_s": wall,
                "peak_rss_mb": peak_mb,
                "solved": len(errors),
                "n": len(frames),
                "boresight_error_arcsec": errors,
                "database_mb_on_disk": db_bytes / 1e6,
                "stderr": stderr,
            }
            print(
                f"{mode}: {len(errors)}/{len(frames)} solved in {wall:.1f} s, peak RSS "
                f"{peak_mb:.0f} MB, database {db_bytes / 1e6:.0f} MB on disk, boresight error "
                f"{', '.join(f'{e:.2f}' for e in errors)} arcsec"
            )
            if stderr:
                print(f"  stderr: {stderr}")
        out["runs"] = runs
    RESULTS.mkdir(parents=True, exist_ok=True)
    with atomic_write(RESULTS / "narrow_field.json") as f:
        json.dump(out, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
