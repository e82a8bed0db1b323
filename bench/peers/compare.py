"""Peer comparison, starsense vs cedar-solve, tetra3rs and astrometry.net: `make bench-peers`.

Same inputs, same run, one thread each. cedar-solve 0.5.1 (PyPI) needs NumPy < 2, so it runs in
its own venv, ``bench/peers/.venv``, as a subprocess, ``bench/peers/run_cedar.py``; tetra3rs
(PyPI wheel) likewise in ``bench/peers/.venv-tetra3rs`` through ``run_tetra3rs.py`` (both venvs
made by ``make bench-peers``, git-ignored). Both read an .npz this script writes; starsense runs
in-process here; a peer that is missing is said so and skipped. Inputs:

(a) synthetic centroid sets: 2,001 Fibonacci boresights (random roll), 15 deg across a
    1280 x 960 pinhole detector, the 20 brightest bundled-Hipparcos stars (V <= 9) in the frame,
    0.3 px Gaussian centroid noise, 2 false stars at random positions and ranks (the standard
    set), or 1 px, 6 false stars and 30 % of the stars missing (the hard set); each at the
    project's seed and at a fresh seed drawn at run time (printed; ``--fresh-seed`` repeats
    one). Every solver is told the field (15 deg) and called through its public API:
    starsense's ``Solver(fov_rad=...).solve_centroids(xy, (width, height))``, tetra3rs's
    ``solve_from_centroids``, cedar-solve's ``solve_from_centroids``; starsense's inner
    identifier (``HashIdentifier(database)(pinhole_vectors(...))``, which no user calls) is a
    second, labelled line. Centroids that noise put more than 2 px outside the image (which
    ``solve_centroids`` refuses as not of this image) are left out for every solver. Wrong:
    boresight more than 1 arcmin from the truth.
(b) the eight ESA frames: (b1) both solvers on starsense's centroids (the detection of
    ``Solver(sensor="esa_blackfly")``), field 11.42 deg given; (b2) each with its own extraction
    from the image (starsense's full pipeline vs cedar's ``solve_from_image``). Wrong: boresight
    more than 15 arcsec from reference.json.
(c) the real frame sets with a reference.json (``frame_sets.py``): every folder of the shared
    images (``--sets`` names some); starsense knows nothing, the peers get the camera's nominal
    field as an estimate where the set states one (nothing otherwise); wrong: image centre
    beyond the set's tolerance. ``per_set.py``'s table follows: per set, starsense beside
    astrometry.net (solved, wrong, median time, the time ratio; solve-field bounded by
    ``--astrometry-cpulimit``).

Time per solve is the wall time of one call (centroids in, attitude out; or image in, attitude
out for b2), one thread, databases loaded beforehand; ESA times are the best of 3 per frame.
The centroid sets report the median, 99th percentile and worst call; the machine's load
average is printed and recorded before and after (a shared machine's other work shows in the
tail).
Results: ``bench/results/peers.json`` (atomic write) and tables on stdout, the last one the
side-by-side table of every solver on every input (Markdown).
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
import frame_sets  # noqa: E402
import peer_table  # noqa: E402
import per_set  # noqa: E402
import run_astrometry  # noqa: E402
from run import RESULTS, machine  # noqa: E402

from starsense._io import atomic_write  # noqa: E402
from starsense.catalog import load_catalog  # noqa: E402
from starsense.detect import StarDetector  # noqa: E402
from starsense.errors import InputError  # noqa: E402
from starsense.geometry.attitude import radec_roll_from_attitude  # noqa: E402
from starsense.identify import HashIdentifier, build_database  # noqa: E402
from starsense.identify.centroid_sets import centroid_sets  # noqa: E402
from starsense.sensor import load_sensor  # noqa: E402
from starsense.solve.frames import load_image  # noqa: E402
from starsense.solve.pinhole import pinhole_vectors  # noqa: E402
from starsense.solve.solver import Solver  # noqa: E402

IMAGES = ROOT.parent / "shared" / "data" / "images"
ESA_DIR = IMAGES / "esa"
SYNTH_SIZE = (960, 1280)  # rows, columns
SYNTH_FOV_DEG = 15.0
ARCMIN = math.radians(1.0 / 60.0)
ARCSEC = math.radians(1.0 / 3600.0)


# ---------------------------------------------------------------------------------------------
# inputs


#: the project's seed of the synthetic centroid sets
PROJECT_SEED = 20240605
_STANDARD = {"noise_px": 0.3, "n_false": 2}
_HARD = {"noise_px": 1.0, "n_false": 6, "drop_fraction": 0.3}


def synth_sets(fresh_seed: int) -> dict:
    """The synthetic centroid sets: key -> (label, seed, centroid_sets keyword arguments)."""
    standard = "synthetic 15 deg, 20 stars + 2 false, 0.3 px"
    hard = "synthetic 15 deg, 14 of 20 stars + 6 false, 1 px"
    return {
        "synthetic": (standard, PROJECT_SEED, _STANDARD),
        "synthetic_hard": (hard, PROJECT_SEED, _HARD),
        "synthetic_fresh": (f"{standard}, fresh seed", fresh_seed, _STANDARD),
        "synthetic_hard_fresh": (f"{hard}, fresh seed", fresh_seed, _HARD),
    }


#: the project's synthetic sets: key -> (label, keyword arguments) (bench/lis_speed.py's too)
SYNTH_SETS = {
    key: (label, kw)
    for key, (label, _seed, kw) in synth_sets(0).items()
    if key in ("synthetic", "synthetic_hard")
}


def synthetic_inputs(n: int, seed: int = PROJECT_SEED, **kwargs):
    """Centroid sets (x, y) in pixels, pixel-centre convention, brightest first; truth boresights.

    :func:`starsense.identify.centroid_sets.centroid_sets` on the bundled Hipparcos (V <= 9),
    15 deg across a 1280 x 960 pinhole detector, Fibonacci boresights, random roll. A centroid
    that noise put more than 2 px outside the image is left out (every solver gets the same).
    """

    sets = centroid_sets(
        load_catalog("hipparcos"),
        n,
        fov_rad=math.radians(SYNTH_FOV_DEG),
        image_size=SYNTH_SIZE,
        seed=seed,
        **kwargs,
    )
    rows, cols = SYNTH_SIZE
    xy, offsets = sets.xy, np.asarray(sets.offsets)
    inside = np.all((xy >= -2.5) & (xy <= np.array([cols + 1.5, rows + 1.5])), axis=1)
    kept = np.concatenate([[0], np.cumsum(inside)])[offsets]  # new offsets
    return xy[inside], kept, sets.boresights


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
    public = Solver(fov_rad=fov)  # the README's call: Solver(fov_rad=...).solve_centroids(...)
    public.prepare()  # its database loaded, once
    size = (SYNTH_SIZE[1], SYNTH_SIZE[0])  # width, height
    # each call timed in a pass of its own over the sets, as the peers' are (alternating the
    # public call with the inner identifier's own copy of the database evicts each one's
    # tables from the cache between calls)
    for key, (xy, offsets, _bores) in synth_sets.items():
        sets = [xy[offsets[i] : offsets[i + 1]] for i in range(len(offsets) - 1)]
        synth[key], synth[f"{key}_inner"] = [], []
        for pts in sets:
            sol, ms = _best_of(lambda pts=pts: public.solve_centroids(pts, size), 1)
            synth[key].append({**_solution_record(sol, ms), "patterns": _patterns(sol)})
        for pts in sets:

            def solve(pts=pts):
                return identify(
                    pinhole_vectors(pts[:, 0], pts[:, 1], shape=SYNTH_SIZE, fov_rad=fov), fov
                )

            synth[f"{key}_inner"].append(record(*_best_of(solve, 1)))

    esa_fov = 2.0 * sensor.half_fov_rad[0]
    identify_esa = HashIdentifier(build_database(cat, esa_fov))
    same, same_inner = [], []
    esa_public = Solver(sensor=sensor)  # solve_centroids with the sensor's optics
    esa_public.prepare()
    esa_size = (sensor.detector.columns, sensor.detector.rows)
    esa_sets = [exy[eoff[i] : eoff[i + 1]] for i in range(len(names))]
    for pts in esa_sets:
        sol, ms = _best_of(lambda pts=pts: esa_public.solve_centroids(pts, esa_size), 3)
        same.append(_solution_record(sol, ms))
    for pts in esa_sets:

        def solve(pts=pts):
            return identify_esa(sensor.unproject(pts[:, 0], pts[:, 1]), esa_fov)

        same_inner.append(record(*_best_of(solve, 3)))
    own, robust = [], []
    # the default (quick extraction first, the robust one when it does not solve), and the
    # robust extraction alone
    for extraction, records in (("auto", own), ("robust", robust)):
        solver = Solver(sensor=sensor, extraction=extraction)
        solver(images[0])  # database load, once
        for image in images:
            sol, ms = _best_of(lambda image=image, solver=solver: solver(image), 3)
            records.append(_solution_record(sol, ms))
    return {
        "database_load_s": db_s,
        **synth,
        "esa_same_centroids": same,
        "esa_same_centroids_inner": same_inner,
        "esa_own_extraction": own,
        "esa_robust_extraction": robust,
    }


def _patterns(sol) -> int | None:
    """The patterns a solve's last identification looked up (None: it did not get there)."""
    return sol.counts.get("patterns_tried")


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


def astrometry(args, names, sensor, sets, frame_paths) -> tuple[dict | None, str]:
    """solve-field on the ESA frames, ``--frames`` and every set, or (None, why unavailable).

    The ESA frames are solved once: from their set's records when ``esa`` is among the sets.
    """
    cpulimit = args.astrometry_cpulimit
    by_set, why = per_set.astrometry_sets(sets, cpulimit)
    if by_set is None:
        return None, why
    if "esa" in sets:
        solved = dict(zip(sets["esa"]["names"], by_set["esa"], strict=True))
        esa = [solved[n] for n in names]
    else:
        esa_fov_deg = math.degrees(2.0 * sensor.half_fov_rad[0])
        esa = [run_astrometry.solve(ESA_DIR / n, esa_fov_deg, cpulimit) for n in names]
    frames = [run_astrometry.solve(p, None, cpulimit) for p in frame_paths]
    return {"esa_own_extraction": esa, "frames": frames, "sets": by_set}, why


# ---------------------------------------------------------------------------------------------
# cedar-solve's side


def peer_side(python: Path, script: str, module: str, npz: Path, *extra) -> tuple[dict | None, str]:
    """A peer's results, (results, "") or (None, why it is unavailable).

    `script` runs under the peer venv's `python` on `npz`; `module` is what it imports.
    """
    python = python.absolute()  # not resolve(): the venv's python is a symlink out of the venv
    if not python.exists():
        return None, f"{python} not found (make bench-peers creates it)"
    probe = subprocess.run(
        [str(python), "-c", f"import {module}"], capture_output=True, text=True, cwd=HERE
    )
    if probe.returncode:
        last = probe.stderr.strip().splitlines()[-1]
        return None, f"'import {module}' fails in {python}: {last}"
    out = npz.with_suffix(f".{module}.json")
    run = subprocess.run(
        [str(python), str(HERE / script), str(npz), str(out), *map(str, extra)],
        capture_output=True,
        text=True,
        cwd=HERE,
    )
    if run.returncode:
        tail = run.stderr.strip().splitlines()[-1] if run.stderr.strip() else "no stderr"
        return None, f"{script} exited {run.returncode}: {tail}"
    return json.loads(out.read_text()), ""


# ---------------------------------------------------------------------------------------------
# scoring


def _vec(ra_deg, dec_deg):
    ra, dec = math.radians(ra_deg), math.radians(dec_deg)
    return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])


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


def whole_frames(ours, peers, astro, astro_why, reference, names, frame_paths) -> dict:
    """Print and return the whole-frame figures: time per stage, agreement with references."""

    own = "esa_own_extraction"
    theirs = peers.get("cedar")
    split = ag.stage_split(ours[own], theirs[own] if theirs else None)
    ag.print_stage_split(split)
    robust = ours["esa_robust_extraction"]
    print(
        f"starsense with the robust extraction alone: {sum(r['solved'] for r in robust)}/"
        f"{len(robust)} solved, mean {np.mean([r['ms'] for r in robust]):.2f} ms; the default "
        f"solved {sum('quick_ms' not in r['stage_ms'] for r in ours[own])}/{len(ours[own])} "
        "from its quick extraction"
    )
    split["starsense_robust_mean_ms"] = float(np.mean([r["ms"] for r in robust]))
    solvers = {"starsense": ours[own], **{who: r[own] for who, r in peers.items()}}
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


def write_inputs(npz: Path, synth, esa, frame_paths, frame_images, sets) -> None:
    """The .npz every peer reads (see run_cedar.py, run_tetra3rs.py)."""
    names, images, exy, eoff, _reference, sensor = esa
    set_arrays = {}
    for key, fs in sets.items():
        set_arrays[f"set_{key}_fov_deg"] = np.nan if fs["fov_deg"] is None else fs["fov_deg"]
        set_arrays[f"set_{key}_frames"] = np.array(fs["names"])
        for i, im in enumerate(fs["peer_images"]):
            set_arrays[f"set_{key}_image_{i}"] = im
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
        set_names=np.array(list(sets)),
        **set_arrays,
    )


def centroid_scores(ours, peers, synth, esa_truth, labels) -> tuple[dict, list]:
    """Score every solver on the centroid sets and the ESA frames; print one line each.

    ``labels``: synthetic set key -> label. starsense's inner identifier on each synthetic set
    is scored too, on a line of its own (``starsense_inner``), after the public call's.
    """
    sets = [
        *((key, label, synth[key][2], ARCMIN) for key, label in labels.items()),
        ("esa_same_centroids", "ESA frames, starsense's centroids", esa_truth, 15 * ARCSEC),
        ("esa_own_extraction", "ESA frames, each its own extraction", esa_truth, 15 * ARCSEC),
    ]
    results, rows = {}, []
    header = f"{'input':50s} {'solver':14s} {'solved':>8s} {'wrong':>6s} {'mean ms':>9s} "
    print(header + f"{'median ms':>10s} {'p99 ms':>8s} {'worst ms':>9s} {'err as':>7s}")
    for key, label, truth, limit in sets:
        base = label
        entry = {"starsense": peer_table.score(ours[key], truth, limit)}
        for who, theirs in peers.items():
            entry[who] = peer_table.score(theirs[key], truth, limit)
            entry[f"ratio_median_ms_{who}_over_starsense"] = (
                entry[who]["median_ms"] / entry["starsense"]["median_ms"]
            )
        entry["wrong_limit_arcsec"] = limit / ARCSEC
        results[key] = entry
        peer_table.print_scores(label, entry)
        rows.append((label, entry, key == "esa_own_extraction"))
        loose = peers.get("tetra3rs", {}).get(f"{key}_loose")
        if loose is not None:  # run_tetra3rs.LOOSE
            entry["tetra3rs_loose"] = peer_table.score(loose, truth, limit)
            label = f"{label}, tetra3rs match_max_error 0.003"
            peer_table.print_scores(label, {"tetra3rs": entry["tetra3rs_loose"]})
            rows.append((label, {"tetra3rs": entry["tetra3rs_loose"]}, False))
        if f"{key}_inner" in ours:  # the identifier inside the public call, labelled
            inner = peer_table.score(ours[f"{key}_inner"], truth, limit)
            entry["starsense_inner"] = inner
            name = f"{base}: starsense's inner identifier, not a public call"
            peer_table.print_scores(name, {"starsense": inner})
            rows.append((name, {"starsense": inner}, False))
    return results, rows


def _load(avg) -> str:
    return ", ".join(f"{v:.2f}" for v in avg)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cedar-python", type=Path, default=HERE / ".venv" / "bin" / "python")
    parser.add_argument(
        "--tetra3rs-python", type=Path, default=HERE / ".venv-tetra3rs" / "bin" / "python"
    )
    parser.add_argument("-n", type=int, default=2001, help="Fibonacci boresights (default 2001)")
    parser.add_argument(
        "--frames", type=Path, help="also solve every image of this folder with each solver"
    )
    parser.add_argument("--sets", nargs="*", help="frame sets of the shared data (default: all)")
    parser.add_argument("--no-astrometry", action="store_true", help="skip solve-field")
    parser.add_argument(
        "--astrometry-cpulimit",
        type=int,
        default=per_set.CPULIMIT_S,
        help=f"solve-field's CPU limit per frame, s (default {per_set.CPULIMIT_S})",
    )
    parser.add_argument(
        "--fresh-seed", type=int, help="the fresh seed of the centroid sets (default: drawn now)"
    )
    args = parser.parse_args(argv)
    frame_paths, frame_images = frames_dir(args.frames) if args.frames else ([], [])
    fresh = args.fresh_seed
    if fresh is None:
        fresh = int(np.random.SeedSequence().generate_state(1)[0])
    chosen = synth_sets(fresh)
    labels = {key: label for key, (label, _seed, _kw) in chosen.items()}
    load_before = os.getloadavg()

    print(
        f"generating inputs: {args.n} synthetic centroid sets (seeds {PROJECT_SEED} and fresh "
        f"{fresh}), 8 ESA frames ...; load average {_load(load_before)}",
        flush=True,
    )
    synth = {key: synthetic_inputs(args.n, seed, **kw) for key, (_l, seed, kw) in chosen.items()}
    esa = esa_inputs()
    names, _images, _exy, _eoff, reference, sensor = esa
    esa_truth = [_vec(reference[n]["ra_deg"], reference[n]["dec_deg"]) for n in names]
    sets = per_set.load_sets(args.sets)

    peers, missing = {}, {}
    with tempfile.TemporaryDirectory(prefix="starsense-peers-") as tmp:
        npz = Path(tmp) / "inputs.npz"
        write_inputs(npz, synth, esa, frame_paths, frame_images, sets)
        print("starsense ...", flush=True)
        ours = starsense_side(synth, esa)
        ours["frames"] = starsense_frames(frame_images)
        ours["sets"] = {key: frame_sets.starsense_set(fs) for key, fs in sets.items()}
        for who, python, script, module, extra in (
            ("cedar", args.cedar_python, "run_cedar.py", "tetra3", ()),
            ("tetra3rs", args.tetra3rs_python, "run_tetra3rs.py", "tetra3rs", (HERE / ".cache",)),
        ):
            print(f"{who} (subprocess in its venv) ...", flush=True)
            result, why = peer_side(python, script, module, npz, *extra)
            if result is None:
                missing[who] = why
                print(f"{who} unavailable: {why}")
            else:
                peers[who] = result
    astro, astro_why = None, "skipped (--no-astrometry)"
    if not args.no_astrometry:
        print("astrometry.net solve-field ...", flush=True)
        astro, astro_why = astrometry(args, names, sensor, sets, frame_paths)
    if astro is None:
        missing["astrometry.net"] = astro_why

    load_after = os.getloadavg()
    print(f"load average (1, 5, 15 min): before {_load(load_before)}, after {_load(load_after)}")
    results, rows = centroid_scores(ours, peers, synth, esa_truth, labels)
    set_results, set_rows = frame_sets.set_scores(sets, ours, peers, astro)
    whole = whole_frames(ours, peers, astro, astro_why, reference, names, frame_paths)
    side_by_side = peer_table.table(rows + set_rows, missing)
    print("\nside by side (one thread each, same run):\n" + side_by_side)
    astro_sets = None if astro is None else astro["sets"]
    sets_rows = per_set.per_set(sets, ours["sets"], astro_sets)
    sets_table = per_set.table(sets_rows, astro_why, astro is not None, args.astrometry_cpulimit)
    print("\nper set, starsense beside astrometry.net:\n" + sets_table)

    record = {
        "name": "peers",
        "description": "starsense and its peers on the same inputs (bench/peers/compare.py)",
        "results": results,
        "frame_sets": set_results,
        "whole_frames": whole,
        "table_markdown": side_by_side,
        "per_set": sets_rows,
        "per_set_table_markdown": sets_table,
        "astrometry_cpulimit_s": args.astrometry_cpulimit,
        "starsense": {"database_load_s": ours["database_load_s"], "machine": machine()},
        "seeds": {"project": PROJECT_SEED, "fresh": fresh},
        "load_average": {"before": list(load_before), "after": list(load_after)},
        **{
            who: {k: r.get(k) for k in ("version", "database", "database_load_s", "machine")}
            for who, r in peers.items()
        },
        "unavailable": missing,
        "per_case": {
            **{
                f"{key}_unsolved": {
                    who: [
                        {"index": i, "status": r.get("status")}
                        for i, r in enumerate(recs[key])
                        if not r["solved"]
                    ]
                    for who, recs in (("starsense", ours), *peers.items())
                }
                for key in chosen
            },
            "esa_names": names,
            **{
                f"{who}_{k}": recs[k]
                for who, recs in (("starsense", ours), *peers.items())
                for k in ("esa_same_centroids", "esa_own_extraction")
            },
            "frames_names": [p.name for p in frame_paths],
            "starsense_frames": ours["frames"],
            **({"cedar_frames": peers["cedar"].get("frames", [])} if "cedar" in peers else {}),
            **({f"astrometry_{k}": v for k, v in astro.items()} if astro else {}),
        },
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    with atomic_write(RESULTS / "peers.json") as f:
        json.dump(record, f, indent=2)
    print(f"written {RESULTS / 'peers.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
