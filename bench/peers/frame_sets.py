"""Real frame sets of the peer comparison: every frame of a folder with a reference.json.

A set is a folder of frames from one camera with ``reference.json``: ``frames`` maps each frame's
name to its reference, either ``{"reference": {"ra_deg", "dec_deg", ...} or null}`` or the
reference itself (``{"ra_deg", "dec_deg", ...}``); ``tolerance_arcsec`` (absent: 15 arcsec,
:data:`DEFAULT_TOLERANCE_ARCSEC`); ``camera`` (optional) with ``horizontal_fov_deg``, or
``plate_scale_arcsec_per_px`` and ``width_px``, for the camera's nominal field (absent: the
field is unknown to every solver). Each solver is scored against the references by the
separation of its boresight (the image centre) from the reference's: a solution further than
the set's tolerance is wrong; a solution claimed on a frame with no reference (no independent
solver solved it) is counted apart, as "claimed". starsense reads each frame with its own reader
(a format it cannot read is a failure, status ``unreadable``); the peers get the pixels as
Pillow reads them, in grey (8-bit frames stay 8-bit, 16-bit stay 16-bit).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from starsense.errors import InputError
from starsense.solve.frames import load_image
from starsense.solve.solver import Solver

ARCSEC_PER_RAD = 180.0 * 3600.0 / np.pi
#: the wrong limit of a set whose reference.json states no tolerance: the 15 arcsec that
#: compare.py applies to the ESA frames (their reference.json: "agreement within 10-15 arcsec on
#: boresight is the useful bar")
DEFAULT_TOLERANCE_ARCSEC = 15.0
LABELS = {"cedar": "cedar-solve"}


def _grey_pixels(path: Path) -> np.ndarray:
    """The frame as Pillow reads it, one grey channel (uint8, or uint16 for 16-bit frames)."""
    from PIL import Image

    with Image.open(path) as im:
        if im.mode in ("I;16", "I;16B", "I;16L", "I"):
            return np.asarray(im).astype(np.uint16)
        return np.asarray(im.convert("L"))


def discover(images: Path) -> list[str]:
    """The names of the sets under `images`: every sub-folder with a reference.json, sorted."""
    if not images.is_dir():
        return []
    return sorted(p.name for p in images.iterdir() if (p / "reference.json").is_file())


def _reference(entry) -> dict | None:
    """A frame's reference from either layout of reference.json (None: no reference)."""
    if not isinstance(entry, dict):
        return None
    if "reference" in entry:
        return entry["reference"]
    return entry if "ra_deg" in entry and "dec_deg" in entry else None


def nominal_fov_deg(camera: dict | None) -> float | None:
    """The camera's horizontal field, deg, as reference.json gives it (None: unknown)."""
    camera = camera or {}
    if camera.get("horizontal_fov_deg") is not None:
        return float(camera["horizontal_fov_deg"])
    scale, width = camera.get("plate_scale_arcsec_per_px"), camera.get("width_px")
    if scale is not None and width is not None:
        return float(scale) * float(width) / 3600.0
    return None


def load_set(folder: Path) -> dict:
    """One set: names, references (None where null), tolerance, nominal field, pixels."""
    meta = json.loads((folder / "reference.json").read_text())
    names = list(meta["frames"])
    own, own_error = [], []
    for name in names:
        try:
            own.append(np.asarray(load_image(folder / name)))
            own_error.append(None)
        except (InputError, OSError, ValueError) as exc:
            own.append(None)
            own_error.append(str(exc).splitlines()[0])
    tolerance = meta.get("tolerance_arcsec")
    return {
        "name": folder.name,
        "folder": folder,
        "names": names,
        "references": [_reference(meta["frames"][n]) for n in names],
        "tolerance_arcsec": float(tolerance if tolerance is not None else DEFAULT_TOLERANCE_ARCSEC),
        "tolerance_stated": tolerance is not None,
        "fov_deg": nominal_fov_deg(meta.get("camera")),
        "peer_images": [_grey_pixels(folder / n) for n in names],
        "own_images": own,
        "own_errors": own_error,
    }


def starsense_set(frame_set: dict) -> list[dict]:
    """starsense with nothing known (the field found by its scale search), one thread.

    Each frame is solved once untimed (database builds or loads) and once timed.
    """
    solver = Solver()
    out = []
    for image, error in zip(frame_set["own_images"], frame_set["own_errors"], strict=True):
        if image is None:
            out.append({"solved": False, "status": f"unreadable: {error}", "ms": float("nan")})
            continue
        solver(image)
        t0 = time.perf_counter()
        sol = solver(image)
        ms = (time.perf_counter() - t0) * 1e3
        out.append(
            {
                "solved": bool(sol.solved),
                "status": sol.status,
                "ra_deg": sol.ra_deg,
                "dec_deg": sol.dec_deg,
                "fov_deg": sol.fov_deg,
                "ms": ms,
            }
        )
    return out


def _separation_arcsec(a: dict, b: dict) -> float:
    ra1, de1, ra2, de2 = np.radians([a["ra_deg"], a["dec_deg"], b["ra_deg"], b["dec_deg"]])
    cos = np.sin(de1) * np.sin(de2) + np.cos(de1) * np.cos(de2) * np.cos(ra1 - ra2)
    return float(np.arccos(np.clip(cos, -1.0, 1.0)) * ARCSEC_PER_RAD)


def score_set(records: list[dict], frame_set: dict) -> dict:
    """Solved / wrong / claimed counts and times of one solver on one set.

    Returns
    -------
    dict
        n_reference (frames with a reference), solved and wrong among them, claimed (solutions
        on frames without a reference), median_ms over every frame, per-frame separations.
    """
    tol = frame_set["tolerance_arcsec"]
    seps, claimed = [], 0
    for rec, ref in zip(records, frame_set["references"], strict=True):
        if ref is None:
            claimed += bool(rec["solved"])
            seps.append(None)
        else:
            seps.append(_separation_arcsec(rec, ref) if rec["solved"] else None)
    scored = [s for s in seps if s is not None]
    ms = [r["ms"] for r in records if r["ms"] == r["ms"]]
    return {
        "n": len(records),
        "n_reference": sum(r is not None for r in frame_set["references"]),
        "solved": len(scored),
        "wrong": sum(s > tol for s in scored),
        "claimed_without_reference": claimed,
        "tolerance_arcsec": tol,
        "median_ms": float(np.median(ms)) if ms else None,
        "median_error_arcsec": float(np.median(scored)) if scored else None,
        "per_frame_arcsec": seps,
        "per_frame_status": [r.get("status") for r in records],
    }


def set_scores(sets, ours, peers, astro) -> tuple[dict, list]:
    """Score every solver on every real frame set; print one line each."""
    results, rows = {}, []
    for key, fs in sets.items():
        records = {"starsense": ours["sets"][key]}
        records.update(
            {who: r["sets"][key] for who, r in peers.items() if key in r.get("sets", {})}
        )
        if astro is not None:
            records["astrometry.net"] = astro["sets"][key]
        entry = {who: score_set(recs, fs) for who, recs in records.items()}
        results[key] = entry
        label = f"{key}/ ({len(fs['names'])} frames, within {fs['tolerance_arcsec']:.0f} arcsec)"
        for who, r in entry.items():
            print(
                f"{label:50s} {LABELS.get(who, who):14s} "
                f"{r['solved']:>4d}/{r['n_reference']:<4d}{r['wrong']:>5d} "
                f"claimed w/o reference {r['claimed_without_reference']}, "
                f"median {r['median_ms'] or float('nan'):.1f} ms"
            )
        rows.append((label, entry, False))
    return results, rows
