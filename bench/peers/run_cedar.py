"""cedar-solve's side of the peer comparison; runs in the peers venv (NumPy < 2), not starsense's.

    bench/peers/.venv/bin/python bench/peers/run_cedar.py INPUTS.npz OUT.json

Imports only numpy and cedar-solve (``tetra3``, with its dependency Pillow for the one image
path). INPUTS.npz is written by ``bench/peers/compare.py``; coordinates in it are in starsense's
pixel-centre convention (0, 0 = centre of the top-left pixel) and converted here to cedar's
(0.5, 0.5 = centre of the top-left pixel). Times are wall times around each call, one thread.

Output JSON: per input set, per case, {"solved", "ra_deg", "dec_deg", "roll_deg", "fov_deg",
"matches", "ms"} plus the database's properties and load time.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import json  # noqa: E402
import logging  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from importlib.metadata import version  # noqa: E402

import numpy as np  # noqa: E402
import tetra3  # noqa: E402

warnings.filterwarnings("ignore", category=DeprecationWarning)  # np.math in cedar-solve 0.5.1


def _record(result: dict, ms: float) -> dict:
    ok = result.get("RA") is not None
    return {
        "t_extract_ms": _plain(result.get("T_extract")),
        "t_solve_ms": _plain(result.get("T_solve")),
        "solved": bool(ok),
        "status": str(result.get("status")),
        "ra_deg": float(result["RA"]) if ok else None,
        "dec_deg": float(result["Dec"]) if ok else None,
        "roll_deg": float(result["Roll"]) if ok else None,
        "fov_deg": float(result["FOV"]) if ok else None,
        "matches": int(result["Matches"]) if ok else 0,
        "ms": ms,
    }


def _timed(fn, repeat: int = 1) -> tuple[dict, float]:
    """(result of the fastest call, its time in ms): T_extract / T_solve from the same call."""
    best, result = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        ms = (time.perf_counter() - t0) * 1e3
        if ms < best:
            best, result = ms, out
    return result, best


def main(inputs: str, out: str) -> int:
    logging.getLogger("tetra3.Tetra3").setLevel(logging.WARNING)
    data = np.load(inputs)
    t0 = time.perf_counter()
    t3 = tetra3.Tetra3()  # the database bundled with the wheel (tetra3/data/default_database.npz)
    load_s = time.perf_counter() - t0
    props = {k: _plain(v) for k, v in t3.database_properties.items()}

    # (a) synthetic centroid sets
    height, width = (int(v) for v in data["synth_size"])
    fov_deg = float(data["synth_fov_deg"])
    synth = {}
    for key in (str(k) for k in data["synth_names"]):
        xy, offsets = data[f"{key}_xy"], data[f"{key}_offsets"]
        synth[key] = []
        for i in range(len(offsets) - 1):
            pts = xy[offsets[i] : offsets[i + 1]]
            yx = np.column_stack([pts[:, 1], pts[:, 0]]) + 0.5  # cedar: (y, x), corner origin
            res, ms = _timed(
                lambda yx=yx: t3.solve_from_centroids(yx, (height, width), fov_estimate=fov_deg)
            )
            synth[key].append(_record(res, ms))

    # (b) ESA frames: starsense's centroids, and cedar's own extraction on the image
    esa_size = tuple(int(v) for v in data["esa_size"])
    esa_fov = float(data["esa_fov_deg"])
    names = [str(n) for n in data["esa_names"]]
    exy, eoff = data["esa_xy"], data["esa_offsets"]
    same, own = [], []
    from PIL import Image  # a dependency of cedar-solve

    for i, _name in enumerate(names):
        pts = exy[eoff[i] : eoff[i + 1]]
        yx = np.column_stack([pts[:, 1], pts[:, 0]]) + 0.5
        res, ms = _timed(
            lambda yx=yx: t3.solve_from_centroids(yx, esa_size, fov_estimate=esa_fov), repeat=3
        )
        same.append(_record(res, ms))
        image = Image.fromarray(data[f"esa_image_{i}"])
        res, ms = _timed(lambda image=image: t3.solve_from_image(image, fov_estimate=esa_fov), 3)
        own.append(_record(res, ms))

    frames = []  # compare.py --frames DIR: nothing known
    for i in range(len(data["frames_names"])):
        image = Image.fromarray(data[f"frames_image_{i}"])
        res, ms = _timed(lambda image=image: t3.solve_from_image(image), 1)
        frames.append(_record(res, ms))

    sets = {}  # compare.py's real frame sets: the camera's nominal field as the estimate
    for key in (str(k) for k in data["set_names"]) if "set_names" in data else ():
        set_fov = float(data[f"set_{key}_fov_deg"])
        set_fov = None if set_fov != set_fov else set_fov  # NaN: the set states no field
        sets[key] = []
        for i in range(len(data[f"set_{key}_frames"])):
            image = Image.fromarray(data[f"set_{key}_image_{i}"])
            res, ms = _timed(
                lambda image=image, f=set_fov: t3.solve_from_image(image, fov_estimate=f)
            )
            sets[key].append(_record(res, ms))

    record = {
        "solver": "cedar-solve",
        "version": _version(),
        "database": props,
        "database_load_s": load_s,
        "machine": {
            "python": sys.version.split()[0],
            "numpy": np.__version__,
            "platform": platform.platform(),
            "threads": os.environ.get("OMP_NUM_THREADS"),
        },
        **synth,
        "esa_same_centroids": same,
        "esa_own_extraction": own,
        "frames": frames,
        "sets": sets,
    }
    with open(out, "w") as f:
        json.dump(record, f, default=lambda o: o.item() if hasattr(o, "item") else str(o))
    return 0


def _plain(value):
    """A database property as JSON: arrays to lists, NumPy scalars to Python, NaN to None."""
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        value = value.item()
    return None if isinstance(value, float) and value != value else value


def _version() -> str:
    return version("cedar-solve")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
