"""The ECSS statement held against its own Monte Carlo: st16, esa_blackfly and held-out zoo designs.

    python bench/ecss_coverage.py [--designs 6] [--seed fresh|N] [--trials 200] [--rates 0,1,2]
                                  [--solving 0.9] [--max-mpixel 4] [--no-presets]

For each sensor, ``starsense datasheet --sensor S --statement --rates R --trials T --json`` (one
process per sensor, as a user runs it) and, per axis X, Y, Z and rate, the fraction of the right
solutions within the statement's 1-sigma and 3-sigma totals (the ``coverage`` rows: sky-median
and ensemble bounds). The zoo designs are drawn from a seed printed at the start (``fresh``: drawn
now, never used for a fix); with ``--solving A`` the designs kept are the first whose datasheet
predicts lost in space on at least A of the sky at rest (a design one would fly: the choice
sees the prediction only, never the frames). Writes ``bench/results/ecss_coverage.json`` and
prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import zoo  # noqa: E402
from run import RESULTS, machine  # noqa: E402

from starsense._io import atomic_write  # noqa: E402
from starsense.sensor.dump import sensor_to_toml  # noqa: E402


def _run(sensor: str, trials: int, rates: str) -> dict:
    argv = [
        str(Path(sys.executable).parent / "starsense"), "datasheet", "--sensor", sensor,
        "--statement", "--rates", rates, "--trials", str(trials), "--json",
    ]  # fmt: skip
    t0 = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return {"error": proc.stderr.strip().splitlines()[-1:] or [f"exit {proc.returncode}"]}
    out = json.loads(proc.stdout)
    sheet = out[0] if isinstance(out, list) else out
    return {"coverage": sheet["statement"]["coverage"], "wall_s": wall}


def _fmt(v, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def _cell(row: dict, key: str, spec: str) -> str:
    """A fraction, starred where chance on its frames does not explain it (exact 95 %)."""
    star = "*" if row.get(key.replace("inside_", "consistent_")) is False else ""
    return _fmt(row.get(key), spec) + star


def _line(name: str, rec: dict) -> list[str]:
    """Table rows of one sensor: per rate, the fractions inside (sky-median; ensemble)."""
    if "error" in rec:
        return [f"| {name} | - | - | - | - | {rec['error'][0][:60]} |"]
    by_rate: dict = {}
    for row in rec["coverage"]:
        by_rate.setdefault(row["rate_deg_s"], {})[row["axis"]] = row
    out = []
    for rate, axes in by_rate.items():
        cells = []
        for key, spec in (
            ("inside_1sigma", ".2f"),
            ("inside_3sigma", ".3f"),
            ("inside_1sigma_sky_ensemble", ".2f"),
            ("inside_3sigma_sky_ensemble", ".3f"),
        ):
            cells.append(" / ".join(_cell(axes[a], key, spec) for a in ("X", "Y", "Z")))
        frames = f"{axes['X']['frames']} of {axes['X']['frames_rendered']}"
        out.append(f"| {name} | {rate:g} | {frames} | " + " | ".join(cells) + " |")
    return out


def _availability(toml: Path) -> float:
    """Return the datasheet's predicted lost-in-space availability at rest (one frame rendered)."""
    argv = [
        str(Path(sys.executable).parent / "starsense"), "datasheet", "--sensor", str(toml),
        "--trials", "1", "--json",
    ]  # fmt: skip
    proc = subprocess.run(argv, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        return 0.0
    out = json.loads(proc.stdout)
    sheet = out[0] if isinstance(out, list) else out
    return float((sheet.get("availability") or {}).get("lost_in_space") or 0.0)


def _designs(args, seed: int, tmp: Path, results: dict) -> list[tuple[str, str]]:
    """Return the zoo designs to run: the first ``--designs`` (or, with ``--solving``, the first
    ``--designs`` predicted to solve), each written as a sensor TOML under ``tmp``."""
    out = []
    drawn = zoo.zoo_designs(args.designs if args.solving is None else 40 * args.designs, seed)
    for name, params in drawn:
        if len(out) == args.designs:
            break
        mpixel = params["columns"] * params["rows"] / 1e6
        if args.max_mpixel is not None and mpixel > args.max_mpixel:
            print(f"{name}: {mpixel:.1f} Mpixel, over --max-mpixel: skipped", flush=True)
            results[name] = {"error": [f"skipped: {mpixel:.1f} Mpixel > --max-mpixel"]}
            continue
        path = tmp / f"{name}.toml"
        path.write_text(sensor_to_toml(zoo.make_sensor(name, **params)))
        if args.solving is not None:
            avail = _availability(path)
            if avail < args.solving:
                print(f"{name}: predicted availability {avail:.2f}: not run", flush=True)
                results[name] = {"error": [f"not run: predicted availability {avail:.2f}"]}
                continue
        out.append((name, str(path)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, default=6)
    ap.add_argument("--seed", default="fresh")
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--rates", default="0,1,2")
    ap.add_argument("--out", type=Path, default=RESULTS / "ecss_coverage.json")
    ap.add_argument("--no-presets", action="store_true", help="the zoo designs only")
    ap.add_argument(
        "--max-mpixel", type=float, default=None, help="skip designs with more pixels (said)"
    )
    ap.add_argument(
        "--solving",
        type=float,
        default=None,
        metavar="A",
        help="draw designs until --designs of them are predicted (the datasheet's lost-in-space "
        "availability at rest, no frame seen) to solve on at least this fraction of the sky",
    )
    args = ap.parse_args(argv)
    fresh = args.seed == "fresh"
    seed = int.from_bytes(os.urandom(4), "little") % 1_000_000 if fresh else int(args.seed)
    print(f"held-out zoo designs: seed {seed} ({args.seed})", flush=True)
    results = {}
    header = [
        "| sensor | deg/s | right solutions | within 1 sigma, median (X / Y / Z) | "
        "within 3 sigma, median | within 1 sigma, ensemble | within 3 sigma, ensemble |",
        "|---|---|---|---|---|---|---|",
    ]
    footnote = "\n\n\\* beyond what chance on that many frames explains (exact binomial 95 %)"

    def write() -> str:  # after every sensor: a long run that is stopped keeps what it did
        table = "\n".join(header + [row for n, r in results.items() for row in _line(n, r)])
        table += footnote if "*" in table else ""
        record = {
            "name": "ecss_coverage",
            "seed": seed,
            "seed_drawn_now": fresh,
            "trials": args.trials,
            "rates": args.rates,
            "results": results,
            "table_markdown": table,
            "machine": machine(),
            "date": time.strftime("%Y-%m-%d"),
        }
        with atomic_write(args.out) as f:
            json.dump(record, f, indent=2)
        return table

    with tempfile.TemporaryDirectory() as tmp:
        sensors = [] if args.no_presets else [("st16", "st16"), ("esa_blackfly", "esa_blackfly")]
        sensors += _designs(args, seed, Path(tmp), results)
        for name, spec in sensors:
            print(f"{name} ...", flush=True)
            results[name] = _run(spec, args.trials, args.rates)
            print("\n".join(_line(name, results[name])), flush=True)
            table = write()
    print(table)
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
