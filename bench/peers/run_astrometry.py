"""astrometry.net's ``solve-field`` as a second, independent reference (bench only).

Used by ``bench/peers/compare.py`` when ``solve-field`` is on PATH (Debian packages
``astrometry.net`` and ``astrometry-data-tycho2-10-19``); nothing in starsense depends on it.
Each frame is solved in a temporary directory; the boresight is the WCS (SIP terms included)
evaluated at the image centre, pixel ((W-1)/2, (H-1)/2) (the convention of reference.json), not
CRVAL: ``--crpix-center`` does not keep CRPIX at the centre (on the granasat frames near the
pole the written CRPIX lay hundreds of pixels off it and CRVAL 7-13 deg from the centre), and
``--cpulimit`` bounds a frame that does not solve. astrometry-engine honours that limit only
when it checks its indexes in parallel (dstndstn/astrometry.net issue 6: "--cpulimit ignored
for not(inparallel)", and Debian's /etc/astrometry.cfg does not set ``inparallel``): each run
gets a backend configuration of its own, the system one's index lines with ``inparallel`` and
the CPU limit added (the Tycho-2 10-19 indexes are 36 MB, held in memory at once). A run still
going at three times the limit plus 30 s of wall time is ended with its whole process group
(status ``timeout``). The time is the wall time of the whole ``solve-field`` process (its own
source extraction included), so it carries the process start and index loading that a library
call does not.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
import time
import warnings
from pathlib import Path

#: the backend configuration solve-field reads by default (Debian's package)
SYSTEM_CONFIG = Path("/etc/astrometry.cfg")


def backend_config(folder: Path, cpulimit_s: int) -> Path | None:
    """The system configuration's index lines with ``inparallel`` and the CPU limit (None: no
    system configuration to start from; solve-field then uses its own default)."""
    if not SYSTEM_CONFIG.is_file():
        return None
    keep = [
        line.strip()
        for line in SYSTEM_CONFIG.read_text().splitlines()
        if line.strip().split(" ", 1)[0] in ("add_path", "autoindex", "index")
    ]
    path = folder / "backend.cfg"
    path.write_text("\n".join([*keep, "inparallel", f"cpulimit {cpulimit_s}", ""]))
    return path


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
        ``{"solved", "ra_deg", "dec_deg", "fov_deg", "ms", "status", "cpulimit_s"}``.
    """
    from astropy.io import fits
    from astropy.wcs import WCS, FITSFixedWarning

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
        config = backend_config(Path(tmp), cpulimit_s)
        if config is not None:
            args += ["--backend-config", str(config)]
        t0 = time.perf_counter()
        # a session of its own: on a timeout the engine solve-field started ends with it
        proc = subprocess.Popen(
            [*args, "--dir", tmp, str(path)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        try:
            out, _err = proc.communicate(timeout=cpulimit_s * 3 + 30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            ms = (time.perf_counter() - t0) * 1e3
            return {"solved": False, "status": "timeout", "ms": ms, "cpulimit_s": cpulimit_s}
        ms = (time.perf_counter() - t0) * 1e3
        wcs = Path(tmp) / (Path(path).stem + ".wcs")
        if proc.returncode or not wcs.exists():
            limit = "CPU time limit reached" in out
            status = (
                f"did not solve: --cpulimit {cpulimit_s} s reached"
                if limit
                else f"did not solve (exit {proc.returncode})"
            )
            return {"solved": False, "status": status, "ms": ms, "cpulimit_s": cpulimit_s}
        header = fits.getheader(wcs)
    width_px = float(header.get("IMAGEW", 0.0))
    height_px = float(header.get("IMAGEH", 0.0))
    centre = ((width_px - 1.0) / 2.0, (height_px - 1.0) / 2.0)
    with warnings.catch_warnings():  # a .wcs file has a header and no image: said, harmless
        warnings.simplefilter("ignore", FITSFixedWarning)
        world = WCS(header).all_pix2world([centre], 0)[0]
    ra_deg, dec_deg = (float(v) for v in world)
    scale = abs(float(header["CD1_1"] * header["CD2_2"] - header["CD1_2"] * header["CD2_1"]))
    return {
        "solved": True,
        "status": "solved",
        "ra_deg": ra_deg,
        "dec_deg": dec_deg,
        "fov_deg": width_px * scale**0.5 if width_px else None,
        "ms": ms,
        "cpulimit_s": cpulimit_s,
    }
