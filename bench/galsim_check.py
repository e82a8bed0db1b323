"""The solver and the datasheet against frames GalSim draws (an independent world).

For an IMX296-class camera (1456 x 1088 px of 3.45 um behind 16 mm f/1.4, 100 ms, PSF sigma
1.1 px) and ``--designs`` designs of the sensor zoo (``bench/zoo.py``) drawn from a seed chosen
at run time (held out: printed, never the tuning seed 23), for each PSF kind (Gaussian, Airy,
Moffat beta 2.5, a lens with 0.15 wave of defocus and a little astigmatism: all of the TOML's
FWHM; ``tests/_support/galsim_frames.py``) at rest and at ``--rate-deg-s`` (about a random axis
across the boresight), ``--frames`` random attitudes are drawn by GalSim and solved by the
default ``Solver(sensor)`` (``--solver datasheet``: the datasheet Monte Carlo's, known bias
and weights from each star's signal). Reported per design x PSF x rate:

* solved, wrong: the zoo's (the datasheet Monte Carlo's) definition, a boresight more than
  60 arcsec from the truth;
* the error per axis (``small_rotation_angles`` of truth and solution: x, y cross-boresight,
  z roll; cross is the rms of the two axes), its rms, the median reported 1-sigma
  (``Solution.sigma_rad``), measured / reported (rms error over rms reported sigma) and the
  frames more than 5 reported sigma off on an axis;
* measured / predicted: the datasheet's own check (``score_montecarlo``) with the prediction
  of each frame's attitude (the stars in that field, through the datasheet's star model), and
  the sky-median NEA of the fast prediction (``starsense.analysis.trade.predict``).

The frames hold the sky the datasheet's frames hold (the catalogue and the solver database's
stars it lacks, at the database's epoch). ``python bench/galsim_check.py [--designs N]
[--frames N] [--psf KIND ...] [--rate-deg-s R] [--seed S] [--json PATH] [--jobs N]
[--max-mpixel M]``; one JSON
object per line per design x PSF x rate in ``bench/results/galsim_check.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests" / "_support")]

import zoo  # noqa: E402
from galsim_frames import PSF_KINDS, galsim_frame  # noqa: E402

from starsense._io import atomic_write  # noqa: E402
from starsense.units import ARCSEC, DEG, RAD_TO_ARCSEC  # noqa: E402

RESULTS = HERE / "results"
#: an IMX296-class camera (zoo rules for its well, gain and detection logic)
IMX296 = {
    "focal_length_m": 0.016,
    "columns": 1456,
    "rows": 1088,
    "pitch_um": 3.45,
    "psf_sigma_px": 1.1,
    "exposure_s": 0.1,
    "bit_depth": 12,
    "read_noise_e": 2.2,
    "qe": 0.6,
    "f_number": 1.4,
}
WRONG_RAD = 60.0 * ARCSEC


def _prediction(sensor, sky, database, seed: int):
    """The datasheet's prediction pieces: the fast sheet and what its frame check needs.

    Returns the sheet's dict and (the star model, the stars the solver may fit), or None where
    nothing is detected.
    """
    from starsense.analysis.datasheet.sheet import DatasheetSettings, _sky_noise
    from starsense.analysis.trade import predict, prediction_settings

    sheet = predict(sensor, sky, settings=prediction_settings(rng=seed, n_orientations=500))
    d = sheet.to_dict()
    limit = d.get("limiting_magnitude")
    if limit is None:
        return d, None
    st = DatasheetSettings(n_trials=0, seed=seed, n_orientations=50)
    model, stars, *_ = _sky_noise(sky, sensor, st, (limit, sheet.slew), sensor.fov(), database)
    return d, (model, stars)


def _trial(sensor, solver, sky, psf, k, children, rate_rad_s):
    """Draw and solve trial ``k``; the record montecarlo._result reads (and the sigmas)."""
    from starsense.geometry.attitude import angular_separation, boresight, small_rotation_angles
    from starsense.geometry.sampling import random_attitudes

    rng = np.random.default_rng(children[k])  # the same attitude and rate for every PSF
    truth = random_attitudes(1, rng)[0]
    phi = rng.uniform(0, 2 * np.pi)
    rate = rate_rad_s * np.array([math.cos(phi), math.sin(phi), 0.0])
    t0 = time.perf_counter()
    frame = galsim_frame(sensor, truth, psf=psf, rate_rad_s=rate, catalog=sky, seed=rng)
    render_ms = 1e3 * (time.perf_counter() - t0)
    sol = solver(frame.image)
    err = sig = None
    wrong = False
    if sol.solved:
        wrong = float(angular_separation(boresight(truth), boresight(sol.rotation))) > WRONG_RAD
        if not wrong:
            err = small_rotation_angles(truth, sol.rotation)
            sig = np.asarray(sol.sigma_rad, dtype=float)
    solve_ms = sol.time_ms - sol.stage_ms.get("database_ms", 0.0)
    return (sol.status, sol.solved, wrong, err, sig, truth.as_quat(), render_ms, solve_ms,
            sol.n_matched, rate)  # fmt: skip


def _reported(res) -> dict:
    """Measured against the solution's own sigma, per axis."""
    e, s = res.errors_rad, res.predicted_sigma_rad
    if not len(e):
        return {}
    cross_e = np.sqrt(np.mean(0.5 * (e[:, 0] ** 2 + e[:, 1] ** 2)))
    cross_s2 = 0.5 * (s[:, 0] ** 2 + s[:, 1] ** 2)
    roll_e = np.sqrt(np.mean(e[:, 2] ** 2))
    return {
        "reported_cross_median_arcsec": float(np.median(np.sqrt(cross_s2)) * RAD_TO_ARCSEC),
        "reported_roll_median_arcsec": float(np.median(s[:, 2]) * RAD_TO_ARCSEC),
        "cross_over_reported": float(cross_e / np.sqrt(np.mean(cross_s2))),
        "roll_over_reported": float(roll_e / np.sqrt(np.mean(s[:, 2] ** 2))),
        "beyond_5_reported_sigma": int(np.sum(np.any(np.abs(e) > 5.0 * s, axis=1))),
    }


def _combo(sensor, solver, sky, pred, psf, rate_deg_s, frames, seed):
    """One design x PSF x rate: the row."""
    from starsense.analysis.datasheet.verify import score_montecarlo
    from starsense.analysis.montecarlo import _result

    children = np.random.SeedSequence(seed).spawn(frames)
    rate = rate_deg_s * DEG
    records = [_trial(sensor, solver, sky, psf, k, children, rate) for k in range(frames)]
    res = _result(sensor.name, records, frames, rate, "reed", seed)
    row = {"psf": psf, "rate_deg_s": rate_deg_s, "frames": frames, "frame_seed": seed}
    sheet, pieces = pred
    if pieces is not None:
        scored = score_montecarlo(res, pieces[0], fov=sensor.fov(), stars=pieces[1])
    else:
        scored = score_montecarlo(res, None, fov=None, stars=None, predict=False)
    keep = ("solved", "wrong", "cross_rms_arcsec", "roll_rms_arcsec", "cross_predicted_arcsec",
            "roll_predicted_arcsec", "cross_ratio", "roll_ratio", "cross_ratio_ci95",
            "roll_ratio_ci95", "median_ms", "stars_matched_median")  # fmt: skip
    row.update({k: scored.get(k) for k in keep})
    row.update(_reported(res))
    nea = sheet.get("nea_arcsec") or {}
    for axis in ("cross", "roll"):
        med = (nea.get(axis) or {}).get("median")
        rms = row.get(f"{axis}_rms_arcsec")
        row[f"{axis}_over_sky_median_nea"] = rms / med if (rms and med and not rate_deg_s) else None
    row["render_ms_mean"] = res.time_ms["render"]
    return row


def told_psf(sensor, kind: str):
    """The sensor as its TOML would describe the PSF ``kind`` the frames are drawn with.

    Gaussian, Moffat (beta 2.5) and Airy by name; the optical PSF (defocus and astigmatism) as
    an empirical profile: GalSim's own profile sampled at 8 per pixel without the pixel
    (``method="no_pixel"``), as a lab measurement or a lens model's export gives it.
    """
    from galsim_psf import FWHM_PER_SIGMA, PSF_DEFAULTS, psf_profile

    from starsense.sensor.psf_spec import PSFSpec

    if kind == "gaussian":
        return sensor.with_(psf=PSFSpec())
    if kind == "moffat":
        return sensor.with_(psf=PSFSpec(kind="moffat", moffat_beta=PSF_DEFAULTS["moffat"]["beta"]))
    if kind == "airy":
        obs = PSF_DEFAULTS["airy"]["obscuration"]
        return sensor.with_(psf=PSFSpec(kind="airy", airy_obscuration=obs))
    fwhm = FWHM_PER_SIGMA * sensor.detector.psf_sigma_px
    oversampling, half = 8, math.ceil(6 * fwhm) * 8
    img = psf_profile(kind, fwhm).drawImage(
        nx=2 * half + 1, ny=2 * half + 1, scale=1.0 / oversampling, method="no_pixel"
    )
    spec = PSFSpec(kind="empirical", samples=img.array, oversampling=oversampling,
                   source=f"GalSim {kind}")  # fmt: skip
    return sensor.with_(psf=spec)


def _run_design(job) -> list[dict]:
    name, params, psfs, rates, frames, seed, weighting = job
    if weighting == "told":
        return _run_told(job)
    from starsense.analysis.inputs import at_epoch, completed_sky
    from starsense.catalog import load_catalog
    from starsense.solve import Solver

    sensor = zoo.make_sensor(name, **params)
    solver = (
        Solver(sensor)  # the default: what a user gets
        if weighting == "default"
        else Solver(sensor, background="known", centroid_sigma_px="snr")  # the datasheet's
    )
    database = solver.catalog
    sky = at_epoch(completed_sky(load_catalog("hipparcos"), database), database.epoch_yr)
    seeds = np.random.SeedSequence(seed).generate_state(len(rates) + 1)
    rows = []
    pred = _prediction(sensor, sky, database, int(seeds[-1]))
    for j, rate in enumerate(rates):
        for psf in psfs:
            t0 = time.perf_counter()
            row = _combo(sensor, solver, sky, pred, psf, rate, frames, int(seeds[j]))
            row = {"design": name, "params": params, "solver": weighting, **row,
                   "seconds": time.perf_counter() - t0,
                   "limiting_magnitude": pred[0].get("limiting_magnitude")}  # fmt: skip
            rows.append(row)
            _print(row)
    return rows


def _run_told(job) -> list[dict]:
    """Each PSF kind with the sensor's TOML giving it (the solver and the prediction know it)."""
    name, params, psfs, rates, frames, seed, _ = job
    from starsense.analysis.inputs import at_epoch, completed_sky
    from starsense.catalog import load_catalog
    from starsense.solve import Solver

    drawn = zoo.make_sensor(name, **params)
    seeds = np.random.SeedSequence(seed).generate_state(len(rates) + 1)
    rows = []
    for psf in psfs:
        sensor = told_psf(drawn, psf)
        solver = Solver(sensor)
        database = solver.catalog
        sky = at_epoch(completed_sky(load_catalog("hipparcos"), database), database.epoch_yr)
        pred = _prediction(sensor, sky, database, int(seeds[-1]))
        for j, rate in enumerate(rates):
            t0 = time.perf_counter()
            row = _combo(drawn, solver, sky, pred, psf, rate, frames, int(seeds[j]))
            row = {"design": name, "params": params, "solver": "told", **row,
                   "seconds": time.perf_counter() - t0,
                   "limiting_magnitude": pred[0].get("limiting_magnitude")}  # fmt: skip
            rows.append(row)
            _print(row)
    return rows


def _fmt(v, spec=".2f"):
    return "-" if v is None else format(v, spec)


def _print(r: dict) -> None:
    print(
        f"{r['design']:12s} {r['psf']:8s} {r['rate_deg_s']:g} deg/s: "
        f"{r['solved']}/{r['frames']} solved, {r['wrong']} wrong; rms "
        f'{_fmt(r.get("cross_rms_arcsec"))}/{_fmt(r.get("roll_rms_arcsec"))}"; '
        f"meas/reported {_fmt(r.get('cross_over_reported'))}/{_fmt(r.get('roll_over_reported'))}"
        f"; meas/predicted {_fmt(r.get('cross_ratio'))}/{_fmt(r.get('roll_ratio'))}; "
        f"{r['seconds']:.0f} s",
        flush=True,
    )


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, default=6, help="held-out zoo designs (plus IMX296)")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--psf", nargs="+", choices=PSF_KINDS, default=list(PSF_KINDS))
    ap.add_argument("--rate-deg-s", type=float, default=1.0, help="the rate besides rest")
    ap.add_argument("--seed", type=int, default=None, help="root seed (default: fresh)")
    ap.add_argument("--json", default=str(RESULTS / "galsim_check.json"))
    ap.add_argument("--jobs", type=int, default=1, help="designs at once (one process each)")
    ap.add_argument("--no-imx296", action="store_true", help="zoo designs only")
    ap.add_argument("--max-mpixel", type=float, default=None, help="only designs this small")
    ap.add_argument(
        "--solver",
        choices=("default", "datasheet", "told"),
        default="default",
        help="Solver(sensor) with the width alone (a Gaussian), the datasheet Monte Carlo's "
        "(known bias), or 'told': the sensor's [psf] gives the shape drawn",
    )
    args = ap.parse_args(argv)
    seed = args.seed if args.seed is not None else int.from_bytes(os.urandom(4), "little")
    zoo_seed = int(np.random.SeedSequence(seed).generate_state(1)[0])
    if zoo_seed == 23:
        zoo_seed += 1  # never the tuning set
    print(f"root seed {seed}; held-out zoo seed {zoo_seed}", flush=True)
    designs = [] if args.no_imx296 else [("imx296_16mm", IMX296)]
    designs += zoo.zoo_designs(args.designs, zoo_seed)
    rates = [0.0, args.rate_deg_s] if args.rate_deg_s else [0.0]
    seeds = np.random.SeedSequence(seed).spawn(len(designs))
    jobs = [(n, p, args.psf, rates, args.frames, int(s.generate_state(1)[0]), args.solver)
            for (n, p), s in zip(designs, seeds, strict=True)]  # fmt: skip
    if args.max_mpixel is not None:  # each design keeps its frames' seed either way
        for n, p, *_ in jobs:
            mpx = p["columns"] * p["rows"] / 1e6
            if mpx > args.max_mpixel:
                print(f"{n}: {mpx:.1f} Mpixel, over --max-mpixel: skipped", flush=True)
        jobs = [j for j in jobs if j[1]["columns"] * j[1]["rows"] <= args.max_mpixel * 1e6]
    rows: list[dict] = []
    ctx = mp.get_context("spawn")
    with ctx.Pool(max(1, args.jobs), maxtasksperchild=1) as pool:
        for part in pool.imap(_run_safely, jobs):
            rows += part
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            with atomic_write(args.json) as fh:
                for r in rows:
                    fh.write(json.dumps({"root_seed": seed, "zoo_seed": zoo_seed, **r}) + "\n")
    return 0


def _run_safely(job) -> list[dict]:
    """A design the package cannot handle is a row saying so, not the end of the run."""
    try:
        return _run_design(job)
    except Exception as exc:
        print(f"{job[0]}: failed: {type(exc).__name__}: {exc}", flush=True)
        return [{"design": job[0], "params": job[1], "error": f"{type(exc).__name__}: {exc}"}]


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
