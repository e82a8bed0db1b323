"""The sensor zoo: the datasheet judged over seeded, physically sensible designs nobody tuned it on.

:func:`zoo_designs` draws designs across field 3-60 deg, pixel pitch 2-25 um, 512-4096
columns (4:3), PSF sigma 0.5-3 px (undersampled included), exposure 10 ms-1 s, 8-16 bit, read
noise 1-30 e-, QE 0.3-0.8 and f/0.95-f/4 (log-uniform where the range spans a decade). The
detector is made consistent: full well 1,500 e- per square micrometre of pixel (a CMOS/CCD
rule of thumb), the gain maps the full well onto the ADC's range unless that would put the
read noise below one count (then one count per read-noise electron-rms).

The detection logic is derived from each design's noise, not copied from a preset:

* sigma = noise of an empty pixel in counts (read noise and dark shot noise times the gain, and
  the ADC's 1/sqrt(12), :func:`starsense.analysis.datasheet.checks.empty_pixel_sigma_counts`);
* lit pixel: 5 sigma, at least 1 count;
* contiguous pixels: 2 for an undersampled PSF (sigma < 0.8 px), else 3;
* integrated: 5 sigma over the PSF's noise-equivalent area, ``5 sigma sqrt(4 pi s^2)`` (s the
  PSF sigma, at least 1 px^2), at least lit x pixels.

For each design the datasheet runs at rest and at 1 deg/s (``--frames`` each) and the row
records the measured / predicted ratios per axis (with their 95 % intervals over the frames, and
the robust ones, from the median normalised error), the stars matched, solved, wrong, time and
peak memory (each design in its own process, so the peak is that design's); the file's summary
counts the designs whose ratios both lie in 0.8-1.25, at rest and at 1 deg/s. ``python
bench/zoo.py [--designs N] [--frames N] [--only NAME]``; results in ``bench/results/zoo.json``.
"""

from __future__ import annotations

import argparse
import inspect
import json
import math
import multiprocessing as mp
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

from starsense._io import atomic_write
from starsense.analysis.datasheet.checks import empty_pixel_sigma_counts
from starsense.detect.threshold import StarDetector
from starsense.sensor import DetectionThresholds, Sensor
from starsense.sensor.detector import Detector
from starsense.sensor.optics import Optics
from starsense.solve.streak_model import MIN_STREAK_SIGMAS

RESULTS = Path(__file__).resolve().parent / "results"
#: full-well capacity per square micrometre of pixel, e- (typical of CMOS and CCD pixels)
FULL_WELL_E_PER_UM2 = 1500.0


def _log_uniform(rng, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def detection_for(det: Detector, exposure_s: float) -> DetectionThresholds:
    """Return the detection logic of a detector from its noise (the module docstring)."""
    probe = Sensor(
        name="probe",
        optics=Optics(focal_length_m=0.05, aperture_m=0.025),
        detector=det,
        exposure_s=exposure_s,
        detection=DetectionThresholds(lit_pixel_counts=1.0, min_integrated_counts=0.0),
    )
    sigma = empty_pixel_sigma_counts(probe)
    lit = max(5.0 * sigma, 1.0)
    n_pix = 2 if det.psf_sigma_px < 0.8 else 3
    area = max(4.0 * math.pi * det.psf_sigma_px**2, 1.0)
    integrated = max(5.0 * sigma * math.sqrt(area), lit * n_pix)
    return DetectionThresholds(
        lit_pixel_counts=round(lit, 3), min_pixels=n_pix, min_integrated_counts=round(integrated, 3)
    )


def make_sensor(name: str, **p) -> Sensor:
    """Return a design from its parameters (field or focal length, pixel, optics, detector)."""
    bits = int(p["bit_depth"])
    full_well = FULL_WELL_E_PER_UM2 * (p["pitch_um"]) ** 2
    # the full well onto the ADC's range, but the read noise at least one count (a camera
    # with few bits saturates its ADC before its well rather than quantise its noise away)
    gain = max((2**bits - 1) / full_well, 1.0 / p["read_noise_e"])
    det = Detector(
        columns=int(p["columns"]),
        rows=int(p["rows"]),
        pixel_pitch_m=p["pitch_um"] * 1e-6,
        gain_counts_per_e=max(gain, 1e-4),
        read_noise_e=p["read_noise_e"],
        bit_depth=bits,
        psf_sigma_px=p["psf_sigma_px"],
        qe_mean=p["qe"],
        passband_nm=(400.0, 900.0),
        full_well_e=full_well,
    )
    focal = p.get("focal_length_m")
    if focal is None:
        half = 0.5 * det.columns * det.pixel_pitch_m
        focal = half / math.tan(math.radians(0.5 * p["fov_deg"]))
    return Sensor(
        name=name,
        optics=Optics(focal_length_m=focal, aperture_m=focal / p["f_number"], transmission=0.8),
        detector=det,
        exposure_s=p["exposure_s"],
        detection=detection_for(det, p["exposure_s"]),
    )


def zoo_designs(n: int, seed: int = 23) -> list[tuple[str, dict]]:
    """Return ``n`` seeded designs ``(name, parameters)`` across the ranges of the docstring."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        columns = int(round(_log_uniform(rng, 512, 4096) / 16) * 16)
        p = {
            "fov_deg": _log_uniform(rng, 3.0, 60.0),
            "columns": columns,
            "rows": int(round(0.75 * columns / 16) * 16),
            "pitch_um": _log_uniform(rng, 2.0, 25.0),
            "psf_sigma_px": _log_uniform(rng, 0.5, 3.0),
            "exposure_s": _log_uniform(rng, 0.01, 1.0),
            "bit_depth": int(rng.choice([8, 10, 12, 14, 16])),
            "read_noise_e": _log_uniform(rng, 1.0, 30.0),
            "qe": float(rng.uniform(0.3, 0.8)),
            "f_number": float(rng.uniform(0.95, 4.0)),
        }
        out.append((f"zoo{k:02d}", p))
    return out


#: the CCD of the vendor comparison: 768 x 512 px of 9 um behind a 25 mm f/0.95 lens, 1 s
CCD_768 = {
    "focal_length_m": 0.025,
    "columns": 768,
    "rows": 512,
    "pitch_um": 9.0,
    "psf_sigma_px": 0.8,
    "exposure_s": 1.0,
    "bit_depth": 16,
    "read_noise_e": 10.0,
    "qe": 0.5,
    "f_number": 0.95,
}


#: at most this many times the frames asked for, to reach ``--min-right`` right solutions: a
#: design that solves 3 % of its slewing frames still gets ~100 (an rms ratio on 30 frames is
#: known to +-40 % at 95 %, wider than the 0.8-1.25 band it is judged against)
MAX_FRAMES_FACTOR = 40


def _more_frames(right: int, frames: int, min_right: int) -> int:
    """Return the frames that give ~``min_right`` right solutions at ``right`` per ``frames``."""
    if right <= 0 or right >= min_right:
        return 0
    return min(-(-11 * frames * min_right // (10 * right)), MAX_FRAMES_FACTOR * frames)  # 10 % more


def _run_one(args) -> dict:
    name, params, frames, rate_frames, seed, min_right, refine = args
    from starsense.analysis.datasheet import DatasheetSettings, build_datasheet
    from starsense.catalog import load_catalog

    sensor = make_sensor(name, **params)
    t0 = time.perf_counter()
    cat = load_catalog("hipparcos")
    settings = DatasheetSettings(
        n_trials=frames, n_rate_trials=rate_frames, seed=seed, refine=refine
    )
    d = build_datasheet(sensor, cat, settings=settings).to_dict()
    if "monte_carlo" not in d:  # no Monte Carlo: the datasheet says why (a design that sees
        # no star at rest), a row of its own, not a failure of the package
        return {"design": name, "params": params, "skipped": d.get("warnings", ["?"])[0]}
    # a design that seldom solves: more frames (the same seed: the first ones again, then
    # more), until its ratios rest on ~min_right right solutions
    more = {
        "monte_carlo": _more_frames(d["monte_carlo"]["solved"], frames, min_right),
        "monte_carlo_at_rate": _more_frames(
            d["monte_carlo_at_rate"]["solved"], rate_frames, min_right
        ),
    }
    if any(more.values()):
        settings = DatasheetSettings(
            n_trials=more["monte_carlo"], n_rate_trials=more["monte_carlo_at_rate"], seed=seed,
            refine=refine,
        )  # fmt: skip
        again = build_datasheet(sensor, cat, settings=settings).to_dict()
        d.update({k: again[k] for k, n in more.items() if n})
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    row = {"design": name, "params": params, "detection": vars(sensor.detection)}
    row["seconds"] = time.perf_counter() - t0
    row["peak_mb"] = peak_mb
    row["limiting_magnitude"] = d.get("limiting_magnitude")
    row["warnings"] = d.get("warnings", [])
    for key in ("monte_carlo", "monte_carlo_at_rate"):
        mc = d.get(key) or {}
        row[key] = {
            k: mc.get(k)
            for k in (
                "frames",
                "solved",
                "wrong",
                "cross_ratio",
                "roll_ratio",
                "cross_ratio_robust",
                "roll_ratio_robust",
                "cross_ratio_ci95",
                "roll_ratio_ci95",
                "cross_rms_arcsec",
                "roll_rms_arcsec",
                "cross_predicted_arcsec",
                "roll_predicted_arcsec",
                "stars_matched_median",
                "frames_beyond_fit",
                "median_ms",
            )
        }
    if d.get("stars_in_fov"):
        row["stars_in_fov"] = d["stars_in_fov"]["median"]
    return row


def in_band(row: dict, key: str = "monte_carlo") -> bool:
    """Whether measured / predicted lies in 0.8-1.25 on both axes (at rest, or ``key``)."""
    mc = row.get(key) or {}
    return all(
        mc.get(k) is not None and 0.8 <= mc[k] <= 1.25 for k in ("cross_ratio", "roll_ratio")
    )


def _run_safely(job) -> dict:
    """Return a design's row; a design the package cannot handle is a row, not the end."""
    try:
        return _run_one(job)
    except Exception as exc:
        return {"design": job[0], "params": job[1], "error": f"{type(exc).__name__}: {exc}"}


def _print_row(name: str, row: dict) -> None:
    if "error" in row:
        print(f"{name}: failed: {row['error']}", flush=True)
        return
    if "skipped" in row:
        print(f"{name}: no Monte Carlo: {row['skipped']}", flush=True)
        return
    mc, mr = row["monte_carlo"], row["monte_carlo_at_rate"]
    print(
        f"{name}: rest {mc['solved']}/{mc['frames']} solved, {mc['wrong']} wrong, ratios "
        f"{mc['cross_ratio']} / {mc['roll_ratio']}; 1 deg/s {mr['solved']}/{mr['frames']}"
        f", {mr['wrong']} wrong, ratios {mr['cross_ratio']} / {mr['roll_ratio']}; "
        f"{row['seconds']:.0f} s, {row['peak_mb']:.0f} MB",
        flush=True,
    )


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, default=40)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--rate-frames", type=int, default=None)
    ap.add_argument(
        "--seed",
        default="23",
        help="the designs' seed: 23 is the tuning set; 'fresh' draws a held-out one now "
        "(printed, never reused for a fix)",
    )
    ap.add_argument(
        "--refine",
        choices=("model", "cog"),
        default="model",
        help="the solver predicted and checked (the datasheet's --refine)",
    )
    ap.add_argument("--only", default=None, help="run one design (a zoo name, or ccd768)")
    ap.add_argument(
        "--short-streaks",
        action="store_true",
        help="only the designs whose streaks at 1 deg/s are too short to re-centroid over "
        "(at least 2 PSF sigmas, shorter than 2 sigmas plus the centroid margins)",
    )
    ap.add_argument("--max-mpixel", type=float, default=None, help="only designs this small")
    ap.add_argument("--out", default=str(RESULTS / "zoo.json"))
    ap.add_argument("--jobs", type=int, default=1, help="designs run at once (one process each)")
    ap.add_argument(
        "--min-right",
        type=int,
        default=100,
        help="a design with fewer right solutions runs more frames (up to 40x) to reach this",
    )
    args = ap.parse_args(argv)
    if args.seed == "fresh":
        args.seed = int.from_bytes(os.urandom(4), "little") % 1_000_000
        print(f"held-out zoo: seed {args.seed} (drawn now)", flush=True)
    else:
        args.seed = int(args.seed)
    designs = [*zoo_designs(args.designs, args.seed), ("ccd768", CCD_768)]
    if args.only:
        designs = [d for d in designs if d[0] == args.only]
    if args.short_streaks:
        designs = [d for d in designs if d[0] != "ccd768" and short_streaks(d[1])]
    if args.max_mpixel is not None:
        designs = [d for d in designs if d[1]["columns"] * d[1]["rows"] <= args.max_mpixel * 1e6]
    print("designs:", " ".join(d[0] for d in designs), flush=True)
    rows = []
    jobs = [
        (
            name,
            params,
            args.frames,
            args.rate_frames or args.frames,
            args.seed,
            args.min_right,
            args.refine,
        )
        for name, params in designs
    ]
    # one process per design (maxtasksperchild=1): its own peak memory; --jobs designs at once
    ctx = mp.get_context("spawn")
    with ctx.Pool(max(1, args.jobs), maxtasksperchild=1) as pool:
        for job, row in zip(jobs, pool.imap(_run_safely, jobs), strict=True):
            rows.append(row)
            _print_row(job[0], row)
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            with atomic_write(args.out) as f:
                record = {
                    "date": time.strftime("%Y-%m-%d"),
                    "seed": args.seed,
                    "refine": args.refine,
                    **summary(rows),
                    "rows": rows,
                }
                json.dump(record, f, indent=1)
    print(json.dumps(summary(rows)), flush=True)
    return 0


def short_streaks(params: dict, rate_deg_s: float = 1.0) -> bool:
    """Whether a design's streaks at the rate are short: the solver keeps its detections'
    centroids (shorter than ``MIN_STREAK_SIGMAS`` PSF sigmas plus the centroid window's
    margins on each side) but they are at least ``MIN_STREAK_SIGMAS`` sigmas long, near the
    boresight."""
    sensor = make_sensor("probe", **params)
    sigma = float(params["psf_sigma_px"])
    length = math.radians(rate_deg_s) * sensor.exposure_s * sensor.focal_length_px
    margin = inspect.signature(StarDetector).parameters["margin_px"].default
    return MIN_STREAK_SIGMAS * sigma <= length < MIN_STREAK_SIGMAS * sigma + 2.0 * margin


def summary(rows: list[dict]) -> dict:
    """Return the designs that solve (at rest, at the rate) and those with both ratios in band."""
    out = {"designs": len(rows)}
    for key, suffix in (("monte_carlo", ""), ("monte_carlo_at_rate", "_at_rate")):
        seeing = [r for r in rows if (r.get(key) or {}).get("cross_ratio") is not None]
        out[f"with_ratios{suffix}"] = len(seeing)
        out[f"in_band_0.8_1.25{suffix}"] = sum(in_band(r, key) for r in seeing)
        out[f"out_of_band{suffix}"] = [r["design"] for r in seeing if not in_band(r, key)]
    # right solutions at the rate whose streaks no fit holds (not compared): by design
    out["beyond_fit_at_rate"] = {
        r["design"]: n
        for r in rows
        if (n := (r.get("monte_carlo_at_rate") or {}).get("frames_beyond_fit"))
    }
    return out


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
