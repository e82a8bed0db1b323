"""The fast prediction of a new design: time and peak memory, st16 and three non-preset designs.

Each design is predicted (``starsense.analysis.trade.predict``: everything the datasheet
predicts, no frames) in a fresh process after the catalogue is loaded (and its stars fitted
as black bodies, once per session), so no cache of an earlier design helps. Recorded per
design in ``bench/results/predict_<design>.json``: wall and CPU seconds of the prediction
(target <= 2 s on one core), the process's peak resident memory (target <= 500 MB), and the
headline numbers. With ``--trade`` it also times the 24-design trade (``starsense trade
--sensor st16 --vary optics.focal_length_m=0.012:0.035:6 --vary exposure_s=0.05,0.1,0.2,0.4``,
2 workers; target <= 60 s, <= 1 GB) into ``bench/results/trade_st16_24.json``, with the CPU
seconds of the trade's processes alone and the machine's load average. The CPU is shared with
whatever else runs: wall times are noisy, CPU times less so.

The three designs are the non-preset sensors users tried (README): an IMX296-class CMOS
(3.45 um, 25 mm f/1.4, 50 ms), a 768 x 512 9 um CCD behind 25 mm f/0.95 (1 s) and a
1024 x 1024 18 um tracker with 47.7 mm f/1.4 (66 ms). Their detection logic follows their
noise: a pixel is lit 5 read-noise sigma above the bias, a star needs >= 3 lit pixels and an
integrated signal of 10 read-noise sigma of 9 pixels; the gain maps the full well onto the ADC.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def _design(name, *, columns, rows, pitch_m, f_m, f_number, exposure_s, bits, read_e, well_e, psf):
    gain = (2**bits - 1) / well_e
    sigma_counts = read_e * gain
    return {
        "name": name,
        "exposure_s": exposure_s,
        "optics": {"focal_length_m": f_m, "aperture_m": f_m / f_number},
        "detector": {
            "columns": columns,
            "rows": rows,
            "pixel_pitch_m": pitch_m,
            "gain_counts_per_e": gain,
            "read_noise_e": read_e,
            "bit_depth": bits,
            "psf_sigma_px": psf,
            "qe_mean": 0.6,
            "full_well_e": well_e,
        },
        "detection": {
            "lit_pixel_counts": 5.0 * sigma_counts,
            "min_pixels": 3,
            "min_integrated_counts": 10.0 * sigma_counts * 3.0,
            "connectivity": 8,
        },
    }


DESIGNS = {
    "imx296_25mm": _design(
        "imx296_25mm", columns=1456, rows=1088, pitch_m=3.45e-6, f_m=0.025, f_number=1.4,
        exposure_s=0.05, bits=10, read_e=2.2, well_e=10_000.0, psf=1.0,
    ),
    "ccd768_25mm": _design(
        "ccd768_25mm", columns=768, rows=512, pitch_m=9e-6, f_m=0.025, f_number=0.95,
        exposure_s=1.0, bits=12, read_e=8.0, well_e=40_000.0, psf=0.8,
    ),
    "tracker1024_48mm": _design(
        "tracker1024_48mm", columns=1024, rows=1024, pitch_m=18e-6, f_m=0.0477, f_number=1.4,
        exposure_s=0.066, bits=12, read_e=10.0, well_e=150_000.0, psf=1.2,
    ),
}  # fmt: skip


def _one(name: str) -> dict:
    """Predict one design in this process (called in a fresh subprocess)."""
    from starsense.analysis.datasheet.skycache import black_bodies
    from starsense.analysis.trade import predict
    from starsense.catalog import load_catalog
    from starsense.sensor import load_sensor
    from starsense.sensor.load import sensor_from_dict

    cat = load_catalog("hipparcos")
    black_bodies(cat)  # the catalogue's own work, done once per session (trade, page)
    sensor = load_sensor(name) if name not in DESIGNS else sensor_from_dict(DESIGNS[name], name)
    w0, c0 = time.perf_counter(), time.process_time()
    sheet = predict(sensor, cat)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    d = sheet.to_dict()
    return {
        "design": name,
        "wall_s": wall,
        "cpu_s": cpu,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "limiting_magnitude": d.get("limiting_magnitude"),
        "nea_cross_arcsec": (d.get("nea_arcsec") or {}).get("cross", {}).get("median"),
        "nea_roll_arcsec": (d.get("nea_arcsec") or {}).get("roll", {}).get("median"),
        "stars_median": (d.get("stars_in_fov") or {}).get("median"),
    }


def _write(name: str, record: dict) -> None:
    from starsense._io import atomic_write

    record = {
        **record,
        "date": time.strftime("%Y-%m-%d"),
        "cpus": os.cpu_count(),
        "load_average_1min": os.getloadavg()[0],
    }
    with atomic_write(RESULTS / f"{name}.json") as fh:
        json.dump(record, fh, indent=2)


def _trade() -> dict:
    venv = Path(sys.executable).parent
    argv = [
        str(venv / "starsense"), "trade", "--sensor", "st16",
        "--vary", "optics.focal_length_m=0.012:0.035:6", "--vary", "exposure_s=0.05,0.1,0.2,0.4",
        "--workers", "2", "--json",
    ]  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)  # the designs' runs above
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    peak = 0.0
    while proc.poll() is None:
        peak = max(peak, _tree_pss_mb(proc.pid))
        time.sleep(0.25)
    out = proc.stdout.read().decode()
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = usage.ru_utime + usage.ru_stime - before.ru_utime - before.ru_stime
    return {
        "designs": len(out.strip().splitlines()),
        "wall_s": wall,
        "cpu_s": cpu,
        "peak_pss_mb": peak,
        "returncode": proc.returncode,
    }


def _tree_pss_mb(pid: int) -> float:
    """Proportional set size of a process and its children, MB (shared pages counted once)."""
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        try:
            with open(f"/proc/{p}/task/{p}/children") as fh:
                todo += [int(c) for c in fh.read().split()]
            with open(f"/proc/{p}/smaps_rollup") as fh:
                total += sum(int(line.split()[1]) for line in fh if line.startswith("Pss:"))
        except OSError:
            continue
    return total / 1024


def main(argv: list[str]) -> int:
    if argv[:1] == ["--one"]:
        print(json.dumps(_one(argv[1])))
        return 0
    RESULTS.mkdir(parents=True, exist_ok=True)
    ok = True
    for name in ["st16", *DESIGNS]:
        run = subprocess.run(
            [sys.executable, __file__, "--one", name], capture_output=True, text=True, check=True
        )
        rec = json.loads(run.stdout.strip().splitlines()[-1])
        good = rec["cpu_s"] <= 2.0 and rec["peak_rss_mb"] <= 500
        ok &= good
        _write(f"predict_{name}", {**rec, "target_s": 2.0, "target_mb": 500, "meets_target": good})
        print(
            f"predict {name:18s} wall {rec['wall_s']:6.2f} s  cpu {rec['cpu_s']:6.2f} s  "
            f'peak {rec["peak_rss_mb"]:5.0f} MB  NEA {rec["nea_cross_arcsec"]:.3g}"/'
            f'{rec["nea_roll_arcsec"]:.3g}"  {"ok" if good else "SLOW"}',
            flush=True,
        )
    if "--trade" in argv:
        rec = _trade()
        good = rec["wall_s"] <= 60 and rec["peak_pss_mb"] <= 1000 and rec["designs"] == 24
        _write("trade_st16_24", {**rec, "target_s": 60, "target_mb": 1000, "meets_target": good})
        print(
            f"trade st16 x24        wall {rec['wall_s']:6.1f} s  cpu {rec['cpu_s']:6.1f} s  "
            f"peak {rec['peak_pss_mb']:5.0f} MB  {'ok' if good else 'SLOW'}"
        )
        ok &= good
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
