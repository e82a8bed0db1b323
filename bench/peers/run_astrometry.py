"""astrometry.net's ``solve-field`` as a second, independent reference (bench only).

Used by ``bench/peers/compare.py`` when ``solve-field`` is on PATH (Debian packages
``astrometry.net`` and ``astrometry-data-tycho2-10-19``); nothing in starsense depends on it.
Each frame is solved in a temporary directory with ``--crpix-center`` so that the WCS reference
pixel is the image centre and CRVAL is the boresight (the convention of reference.json), and
``--cpulimit`` bounds a frame that does not solve. The time is the wall time of the whole
``solve-field`` process (its own source extraction included), so it carries the process start
and index loading that a library call does not.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path


def available() -> tuple[bool, str]:
    """(True, version) when ``solve-field`` runs, else (False, why not)."""
    exe = shutil.which("solve-field")
    if exe is None:
        return False, (
            "solve-field not on PATH (apt-get install astrometry.net astrometry-data-tycho2-10-19)"
        )
    try:
        out = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return False, f"solve-field does not run: {exc}"
    return True, (out.stdout.strip() or out.stderr.strip() or "unknown version").splitlines()[0]


def solve(path: Path, fov_deg: float | None = None, cpulimit_s: int = 60) -> dict:
    """Solve one frame with ``solve-field``; the record compare.py scores.

    Parameters
    ----------
    path : Path
        The image (any format solve-field reads: FITS, TIFF, PNG, JPEG).
    fov_deg : float, optional
        Horizontal field, deg: searched within +-20 % when given, else unconstrained.
    cpulimit_s : int
        solve-field's CPU limit per frame, s.

    Returns
    -------
    dict
        ``{"solved", "ra_deg", "dec_deg", "fov_deg", "ms", "status"}``.
    """
    from astropy.io import fits

    args = [
        "solve-field",
        "--overwrite",
        "--no-plots",
        "--new-fits",
        "none",
        "--crpix-center",
        "--cpulimit",
        str(cpulimit_s),
    ]
    if fov_deg is not None:
        args += [
            "--scale-units",
            "degwidth",
            "--scale-low",
            f"{0.8 * fov_deg:.4f}",
            "--scale-high",
            f"{1.2 * fov_deg:.4f}",
        ]
    with tempfile.TemporaryDirectory(prefix="starsense-astrometry-") as tmp:
        t0 = time.perf_counter()
        try:
            run = subprocess.run(
                [*args, "--dir", tmp, str(path)],
                capture_output=True,
                text=True,
                timeout=cpulimit_s * 3 + 30,
            )
        except subprocess.TimeoutExpired:
            return {"solved": False, "status": "timeout", "ms": (time.perf_counter() - t0) * 1e3}
        ms = (time.perf_counter() - t0) * 1e3
        wcs = Path(tmp) / (Path(path).stem + ".wcs")
        if run.returncode or not wcs.exists():
            status = f"did not solve within --cpulimit {cpulimit_s} s (exit {run.returncode})"
            return {"solved": False, "status": status, "ms": ms}
        header = fits.getheader(wcs)
    width_px = float(header.get("IMAGEW", 0.0))
    scale = abs(float(header["CD1_1"] * header["CD2_2"] - header["CD1_2"] * header["CD2_1"]))
    return {
        "solved": True,
        "status": "solved",
        "ra_deg": float(header["CRVAL1"]),
        "dec_deg": float(header["CRVAL2"]),
        "fov_deg": width_px * scale**0.5 if width_px else None,
        "ms": ms,
    }
