"""Peer comparison, starsense vs cedar-solve, same inputs, same run: `make bench-peers`.

cedar-solve 0.5.1 (PyPI) needs NumPy < 2, so it runs in its own venv, ``bench/peers/.venv``
(made by ``make bench-peers``; git-ignored), as a subprocess, ``bench/peers/run_cedar.py``, on
an .npz this script writes. starsense runs in-process here. Inputs:

(a) synthetic centroid sets: 2,001 Fibonacci boresights (random roll), 15 deg across a
    1280 x 960 pinhole detector, the 20 brightest bundled-Hipparcos stars (V <= 9) in the frame,
    0.3 px Gaussian centroid noise, 2 false stars at random positions and ranks. Both solvers
    are told the field (15 deg). Wrong: boresight more than 1 arcmin from the truth.
(b) the eight ESA frames: (b1) both solvers on starsense's centroids (the detection of
    ``Solver(sensor="esa_blackfly")``), field 11.42 deg given; (b2) each with its own extraction
    from the image (starsense's full pipeline vs cedar's ``solve_from_image``). Wrong: boresight
    more than 15 arcsec from reference.json.

Time per solve is the wall time of one call (centroids in, attitude out; or image in, attitude
out for b2), one thread, databases loaded beforehand; ESA times are the best of 3 per frame.
Results: ``bench/results/peer_cedar.json`` (atomic write) and a table on stdout.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE.parent))
import agreement as ag  # noqa: E402
import run_astrometry  # noqa: E402
from run import RESULTS, machine  # noqa: E402

from starsense._io import atomic_write  # noqa: E402
from starsense.catalog import load_catalog  # noqa: E402
from starsense.detect import StarDetector  # noqa: E402
from starsense.errors import InputError  # noqa: E402
from starsense.geometry.attitude import angular_separation, radec_roll_from_attitude  # noqa: E402
from starsense.identify import HashIdentifier, build_database  # noqa: E402
from starsense.identify.centroid_sets import centroid_sets  # noqa: E402
from starsense.sensor import load_sensor  # noqa: E402
from starsense.solve.frames import load_image  # noqa: E402
from starsense.solve.pinhole import pinhole_vectors  # noqa: E402
from starsense.solve.solver import Solver  # noqa: E402

ESA_DIR = ROOT.parent / "shared" / "data" / "images" / "esa"
SYNTH_SIZE = (960, 1280)  # rows, columns
SYNTH_FOV_DEG = 15.0
ARCMIN = math.radians(1.0 / 60.0)
ARCSEC = math.radians(1.0 / 3600.0)


# ---------------------------------------------------------------------------------------------
# inputs


#: the synthetic centroid sets: key -> (label, centroid_sets keyword arguments)
SYNTH_SETS = {
    "synthetic": ("synthetic 15 deg, 20 stars + 2 false, 0.3 px", {"noise_px": 0.3, "n_false": 2}),
    "synthetic_hard": (
        "synthetic 15 deg, 14 of 20 stars + 6 false, 1 px",
        {"noise_px": 1.0, "n_false": 6, "drop_fraction": 0.3},
    ),
}


def synthetic_inputs(n: int, seed: int = 20240605, **kwargs):
    """Centroid sets (x, y) in pixels, pixel-centre convention, brightest first; truth boresights.

    :func:`starsense.identify.centroid_sets.centroid_sets` on the bundled Hipparcos (V <= 9),
    15 deg across a 1280 x 960 pinhole detector, Fibonacci boresights, random roll.
    """

    sets = centroid_sets(
        load_catalog("hipparcos"),
        n,
        fov_rad=math.radians(SYNTH_FOV_DEG),
        image_size=SYNTH_SIZE,
        seed=seed,
        **kwargs,
    )
    return sets.xy, sets.offsets, sets.boresights


def esa_inputs():
    """The eight frames, starsense's detections of each (as the pipeline makes them), reference."""

    reference = json.loads((ESA_DIR / "reference.json").read_text())["frames"]
    sensor = load_sensor("esa_blackfly")
    detector = StarDetector(sensor.detection, "cog", background="auto", threshold_sigma=5.0)
    names = sorted(reference)
    images = [load_image(ESA_DIR / name) for name in names]
    xy, offsets = [], [0]
    for image in images:
        det = detector(np.asarray(image))
        xy.append(np.column_stack([det.x, det.y]))
        offsets.append(offsets[-1] + len(det))
    return names, images, np.concatenate(xy), np.asarray(offsets), reference, sensor


# ---------------------------------------------------------------------------------------------
# starsense's side


def _best_of(fn, repeat):
    """(result of the fastest call, its time in ms): stage times then come from the same call."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        ms = (time.perf_counter() - t0) * 1e3
        if ms < best:
            best, out = ms, result
    return out, best


def starsense_side(synth_sets, esa):
    names, images, exy, eoff, _reference, sensor = esa
    cat = load_catalog("hipparcos")
    fov = math.radians(SYNTH_FOV_DEG)
    t0 = time.perf_counter()
    identify = HashIdentifier(build_database(cat, fov))  # built once, then from the disk cache
    db_s = time.perf_counter() - t0

    def record(ident, ms):
        if not ident.solved:
            return {"solved": False, "status": ident.status, "ms": ms}
        ra, dec, roll = (math.degrees(float(a)) for a in radec_roll_from_attitude(ident.rotation))
        return {"solved": True, "ra_deg": ra, "dec_deg": dec, "roll_deg": roll, "ms": ms}

    synth = {}
    for key, (xy, offsets, _bores) in synth_sets.items():
        synth[key] = []
        for i in range(len(offsets) - 1):
            pts = xy[offsets[i] : offsets[i + 1]]

            def solve(pts=pts):
                return identify(
                    pinhole_vectors(pts[:, 0], pts[:, 1], shape=SYNTH_SIZE, fov_rad=fov), fov
                )

            synth[key].append(record(*_best_of(solve, 1)))

    esa_fov = 2.0 * sensor.half_fov_rad[0]
    identify_esa = HashIdentifier(build_database(cat, esa_fov))
    same = []
    for i in range(len(names)):
        pts = exy[eoff[i] : eoff[i + 1]]

        def solve(pts=pts):
            return identify_esa(sensor.unproject(pts[:, 0], pts[:, 1]), esa_fov)

        same.append(record(*_best_of(solve, 3)))
    solver = Solver(sensor=sensor)
    solver(images[0])  # database load, once
    own = []
    for image in images:
        sol, ms = _best_of(lambda image=image: solver(image), 3)
        own.append(_solution_record(sol, ms))
    return {"database_load_s": db_s, **synth, "esa_same_centroids": same, "esa_own_extraction": own}


def _solution_record(sol, ms) -> dict:
    """A Solver solution as compare.py scores it, with its stage times (ms)."""
    return {
        "solved": sol.solved,
        "status": sol.status,
        "ra_deg": sol.ra_deg,
        "dec_deg": sol.dec_deg,
        "roll_deg": sol.roll_deg,
        "fov_deg": sol.fov_deg,
        "ms": ms,
        "stage_ms": dict(sol.stage_ms),
    }


def starsense_frames(images) -> list[dict]:
    """``--frames DIR``: the Solver with nothing known (field found by the scale search)."""

    solver = Solver()
    out = []
    for image in images:
        solver(image)  # database build or load, not timed
        sol, ms = _best_of(lambda image=image: solver(image), 2)
        out.append(_solution_record(sol, ms))
    return out


def astrometry_side(paths, fov_deg) -> tuple[list[dict] | None, str]:
    """solve-field on each frame (run_astrometry.py), or (None, why it is unavailable)."""

    ok, what = run_astrometry.available()
    if not ok:
        return None, what
    return [run_astrometry.solve(p, fov_deg) for p in paths], what


# ---------------------------------------------------------------------------------------------
# cedar-solve's side


def cedar_side(python: Path, npz: Path) -> tuple[dict | None, str]:
    """(results, "") or (None, why cedar-solve is unavailable)."""
    python = python.absolute()  # not resolve(): the venv's python is a symlink out of the venv
    if not python.exists():
        return None, f"{python} not found (make bench-peers creates it)"
    probe = subprocess.run(
        [str(python), "-c", "import tetra3"], capture_output=True, text=True, cwd=HERE
    )
    if probe.returncode:
        return None, f"'import tetra3' fails in {python}: {probe.stderr.strip().splitlines()[-1]}"
    out = npz.with_suffix(".json")
    run = subprocess.run(
        [str(python), str(HERE / "run_cedar.py"), str(npz), str(out)],
        capture_output=True,
        text=True,
        cwd=HERE,
    )
    if run.returncode:
        tail = run.stderr.strip().splitlines()[-1] if run.stderr.strip() else "no stderr"
        return None, f"run_cedar.py exited {run.returncode}: {tail}"
    return json.loads(out.read_text()), ""


# ---------------------------------------------------------------------------------------------
# scoring


def _vec(ra_deg, dec_deg):
    ra, dec = math.radians(ra_deg), math.radians(dec_deg)
    return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])


def score(records, truth_vectors, limit_rad) -> dict:
    n = len(records)
    solved = [r for r in records if r["solved"]]
    errors = [
        float(angular_separation(_vec(r["ra_deg"], r["dec_deg"]), t))
        for r, t in zip(records, truth_vectors, strict=True)
        if r["solved"]
    ]
    wrong = sum(e > limit_rad for e in errors)
    ms = np.array([r["ms"] for r in records])
    return {
        "n": n,
        "solved": len(solved),
        "wrong": int(wrong),
        "solve_rate": len(solved) / n,
        "wrong_rate": wrong / n,
        "correct_rate": (len(solved) - wrong) / n,
        "mean_ms": float(ms.mean()),
        "median_ms": float(np.median(ms)),
        "p99_ms": float(np.percentile(ms, 99)),
        "max_ms": float(ms.max()),
        "median_error_arcsec": float(np.median(errors) / ARCSEC) if errors else None,
    }


def frames_dir(folder: Path) -> tuple[list[Path], list]:
    """The images of ``--frames DIR`` (every file :func:`load_image` reads), sorted by name."""

    if not folder.is_dir():
        raise SystemExit(f"--frames: {folder} is not a directory")
    paths, images = [], []
    for path in sorted(p for p in folder.iterdir() if p.is_file()):
        try:
            images.append(load_image(path))
        except (InputError, OSError, ValueError):
            continue
        paths.append(path)
    if not paths:
        raise SystemExit(f"--frames: no image in {folder}")
    return paths, images


def whole_frames(ours, theirs, astro, astro_why, reference, names, frame_paths) -> dict:
    """Print and return the whole-frame figures: time per stage, agreement with references."""

    own = "esa_own_extraction"
    split = ag.stage_split(ours[own], theirs[own] if theirs else None)
    ag.print_stage_split(split)
    solvers = {"starsense": ours[own]}
    if theirs is not None:
        solvers["cedar"] = theirs[own]
    if astro is not None:
        solvers["astrometry.net"] = astro[own]
    else:
        print(f"astrometry.net unavailable: {astro_why}")
    esa = ag.agreement(solvers, [reference[n] for n in names])
    ag.print_agreement("ESA frames, each solver's own extraction (boresights):", esa, solvers)
    out = {"stage_split": split, "esa_agreement": esa, "astrometry": astro_why}
    if frame_paths:
        fsolvers = {"starsense": ours["frames"]}
        if theirs is not None and theirs.get("frames"):
            fsolvers["cedar"] = theirs["frames"]
        if astro is not None:
            fsolvers["astrometry.net"] = astro["frames"]
        table = ag.agreement(fsolvers)
        ag.print_agreement(f"--frames {frame_paths[0].parent}, nothing known:", table, fsolvers)
        out["frames_agreement"] = table
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cedar-python", type=Path, default=HERE / ".venv" / "bin" / "python")
    parser.add_argument("-n", type=int, default=2001, help="Fibonacci boresights (default 2001)")
    parser.add_argument(
        "--frames", type=Path, help="also solve every image of this folder with each solver"
    )
    parser.add_argument("--no-astrometry", action="store_true", help="skip solve-field")
    args = parser.parse_args(argv)
    frame_paths, frame_images = frames_dir(args.frames) if args.frames else ([], [])

    print(f"generating inputs: {args.n} synthetic centroid sets, 8 ESA frames ...", flush=True)
    synth = {key: synthetic_inputs(args.n, **kw) for key, (_label, kw) in SYNTH_SETS.items()}
    esa = esa_inputs()
    names, images, exy, eoff, reference, sensor = esa
    esa_truth = [_vec(reference[n]["ra_deg"], reference[n]["dec_deg"]) for n in names]

    with tempfile.TemporaryDirectory(prefix="starsense-peers-") as tmp:
        npz = Path(tmp) / "inputs.npz"
        np.savez(
            npz,
            synth_names=np.array(list(synth)),
            synth_size=np.array(SYNTH_SIZE),
            synth_fov_deg=SYNTH_FOV_DEG,
            esa_names=np.array(names),
            esa_xy=exy,
            **{f"{k}_xy": v[0] for k, v in synth.items()},
            **{f"{k}_offsets": v[1] for k, v in synth.items()},
            esa_offsets=eoff,
            esa_size=np.array([sensor.detector.rows, sensor.detector.columns]),
            esa_fov_deg=math.degrees(2.0 * sensor.half_fov_rad[0]),
            **{f"esa_image_{i}": np.asarray(im) for i, im in enumerate(images)},
            frames_names=np.array([p.name for p in frame_paths]),
            **{f"frames_image_{i}": np.asarray(im) for i, im in enumerate(frame_images)},
        )
        print("starsense ...", flush=True)
        ours = starsense_side(synth, esa)
        ours["frames"] = starsense_frames(frame_images)
        print("cedar-solve (subprocess in the peers venv) ...", flush=True)
        theirs, why = cedar_side(args.cedar_python, npz)
    astro, astro_why = None, "skipped (--no-astrometry)"
    if not args.no_astrometry:
        print("astrometry.net solve-field ...", flush=True)
        esa_fov_deg = math.degrees(2.0 * sensor.half_fov_rad[0])
        astro, astro_why = astrometry_side([ESA_DIR / n for n in names], esa_fov_deg)
        if astro is not None:
            astro = {"esa_own_extraction": astro, "frames": astrometry_side(frame_paths, None)[0]}

    sets = [
        *((key, label, synth[key][2], ARCMIN) for key, (label, _kw) in SYNTH_SETS.items()),
        ("esa_same_centroids", "ESA frames, starsense's centroids", esa_truth, 15 * ARCSEC),
        ("esa_own_extraction", "ESA frames, each its own extraction", esa_truth, 15 * ARCSEC),
    ]
    results = {}
    header = f"{'input':50s} {'solver':12s} {'solved':>8s} {'wrong':>6s} {'mean ms':>9s} "
    print(header + f"{'median ms':>10s} {'err as':>7s}")
    for key, label, truth, limit in sets:
        entry = {"starsense": score(ours[key], truth, limit)}
        if theirs is not None:
            entry["cedar"] = score(theirs[key], truth, limit)
            c, s = entry["cedar"], entry["starsense"]
            entry["ratio_mean_ms_cedar_over_starsense"] = c["mean_ms"] / s["mean_ms"]
            entry["ratio_median_ms_cedar_over_starsense"] = c["median_ms"] / s["median_ms"]
        entry["wrong_limit_arcsec"] = limit / ARCSEC
        results[key] = entry
        for who in ("starsense", "cedar"):
            if who not in entry:
                continue
            r = entry[who]
            err = "-" if r["median_error_arcsec"] is None else f"{r['median_error_arcsec']:.1f}"
            print(
                f"{label:50s} {who:12s} {r['solved']:>4d}/{r['n']:<4d}{r['wrong']:>5d} "
                f"{r['mean_ms']:9.2f} {r['median_ms']:10.2f} {err:>7s}"
            )
        if theirs is not None:
            print(
                f"{'':50s} {'ratio':12s} cedar/starsense time: mean "
                f"{entry['ratio_mean_ms_cedar_over_starsense']:.2f}x, median "
                f"{entry['ratio_median_ms_cedar_over_starsense']:.2f}x"
            )
    if theirs is None:
        print(f"cedar-solve unavailable: {why}")
    whole = whole_frames(ours, theirs, astro, astro_why, reference, names, frame_paths)

    record = {
        "name": "peer_cedar",
        "description": "starsense vs cedar-solve on the same inputs (bench/peers/compare.py)",
        "results": results,
        "whole_frames": whole,
        "starsense": {"database_load_s": ours["database_load_s"], "machine": machine()},
        "cedar": (
            {k: theirs[k] for k in ("version", "database", "database_load_s", "machine")}
            if theirs is not None
            else {"unavailable": why}
        ),
        "per_case": {
            **{
                f"{key}_unsolved": {
                    who: [
                        {"index": i, "status": r.get("status")}
                        for i, r in enumerate(recs)
                        if not r["solved"]
                    ]
                    for who, recs in (
                        ("starsense", ours[key]),
                        ("cedar", theirs[key] if theirs else []),
                    )
                }
                for key in SYNTH_SETS
            },
            "esa_names": names,
            **{f"starsense_{k}": ours[k] for k in ("esa_same_centroids", "esa_own_extraction")},
            **(
                {f"cedar_{k}": theirs[k] for k in ("esa_same_centroids", "esa_own_extraction")}
                if theirs is not None
                else {}
            ),
            "frames_names": [p.name for p in frame_paths],
            "starsense_frames": ours["frames"],
            **({"cedar_frames": theirs.get("frames", [])} if theirs is not None else {}),
            **({f"astrometry_{k}": v for k, v in astro.items()} if astro else {}),
        },
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
    }
    RESULTS.mkdir(parents=True, exist_ok=True)

    with atomic_write(RESULTS / "peer_cedar.json") as f:
        json.dump(record, f, indent=2)
    print(f"written {RESULTS / 'peer_cedar.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
