"""The prediction for a camera held against its real frames (``datasheet --against``).

For each real frame, solved with the sensor, the prediction is the same frame as the sensor
says it should look: the catalogue rendered at the frame's solved attitude
(:func:`starsense.render.render_frame`, the sensor's PSF, zero point and distortion residual),
on the frame's own sky (its background map, :func:`starsense.detect.background.
estimate_background`: a ground frame's glow is not the sensor's, and is taken from the frame),
read out with the sensor's gain and noise (:func:`starsense.render.noise.apply_noise`), in
:data:`DRAWS` noise draws. These twins are solved by the same solver, with the robust extraction
alone for both (:mod:`starsense.solve.extraction`: a quick extraction that solves a twin from its
brightest stars, while the frame itself went on to the deeper robust one, would compare a
stopping rule, not the camera), and the frame and its twins give the same four statistics,
measured on the frame and predicted by the twins:

* stars detected and matched per frame;
* the limiting magnitude: the V magnitude at which half the catalogue stars in the field are
  matched (a logistic completeness curve fitted by maximum likelihood over the frames);
* the normalised residual rms: each matched star's residual about the solution (px, both axes)
  over the sigma the twins predict for a star of its magnitude (a fit of the twins' squared
  residuals, ``s^2 = a + b F^-1 + c F^-2`` with ``F = 10^(-0.4 m)``: a floor, photon noise,
  background noise); 1 when the sensor's noise, PSF and distortion residual are the frame's.

A catalogue without V (Gaia's G and BP - RP) takes V from them
(:func:`~starsense.photometry.colour.with_johnson_from_gaia`), for the twins' stars and the
completeness curve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.detect.background import estimate_background
from starsense.errors import InputError
from starsense.photometry.colour import with_johnson_from_gaia
from starsense.render.noise import apply_noise
from starsense.render.scene import render_frame
from starsense.solve import Solver
from starsense.solve.frames import load_image

__all__ = ["DRAWS", "Against", "against"]

#: noise draws of each frame's twin
DRAWS = 3
#: the most of the bright stars a completeness curve lets be missed whatever their light
MAX_LAPSE = 0.2
#: catalogue stars this far inside the detector's edge count for the completeness, px
EDGE_PX = 5.0


@dataclass(frozen=True)
class Against:
    """Measured and predicted statistics of the frames (module docstring).

    Attributes
    ----------
    frames : list of dict
        Per frame: name, status, measured and predicted detected / matched stars.
    skipped : dict
        Frames that did not solve: name -> status.
    quantities : dict
        ``matched_per_frame``, ``detected_per_frame``, ``limiting_magnitude``,
        ``normalised_residual_rms``: each ``{"measured", "predicted", "ratio"}``.
    """

    frames: list
    skipped: dict
    quantities: dict

    def to_dict(self) -> dict:
        """JSON-ready (the ``against`` section)."""
        return {**self.quantities, "frames": self.frames, "skipped": self.skipped}


def _stars_in_field(sensor, rotation, catalog):
    """Return the indices and V magnitudes of the catalogue stars on the detector (EDGE_PX in)."""
    mags = np.asarray(catalog.mags["V"], dtype=float)
    det = sensor.detector
    corners = sensor.unproject(
        np.array([-0.5, det.columns - 0.5, -0.5, det.columns - 0.5]),
        np.array([-0.5, -0.5, det.rows - 0.5, det.rows - 0.5]),
    )
    reach = float(np.max(np.arccos(np.clip(corners[:, 2], -1.0, 1.0))))
    cam = np.asarray(catalog.vectors, dtype=float) @ rotation.as_matrix().T
    # only stars within the corners' angle: a distortion polynomial that turns over past the
    # field would fold stars from outside it onto the detector
    front = np.flatnonzero(cam[:, 2] > math.cos(reach))
    x, y = sensor.project(cam[front])
    inside = (
        (x > EDGE_PX - 0.5)
        & (x < det.columns - 0.5 - EDGE_PX)
        & (y > EDGE_PX - 0.5)
        & (y < det.rows - 0.5 - EDGE_PX)
        & np.isfinite(mags[front])
    )
    idx = front[inside]
    return idx, mags[idx]


def _statistics(sol, sensor, catalog):
    """(mags of field stars, matched?, matched mags, residuals^2 per star (px^2, both axes))."""
    idx, mags = _stars_in_field(sensor, sol.rotation, catalog)
    ids = np.array([c for _, c in sol.matches], dtype=np.int64)
    det = np.array([d for d, _ in sol.matches], dtype=np.intp)
    rows = catalog.index_of(ids) if ids.size else np.zeros(0, np.intp)
    matched = np.isin(idx, rows)
    cam = np.asarray(catalog.vectors, dtype=float)[rows] @ sol.rotation.as_matrix().T
    x, y = sensor.project(cam)
    xy = np.asarray(sol.centroids_px, dtype=float)[det] if ids.size else np.zeros((0, 2))
    r2 = (xy[:, 0] - x) ** 2 + (xy[:, 1] - y) ** 2
    m = np.asarray(catalog.mags["V"], dtype=float)[rows]
    return mags, matched, m, r2


def _limit(mags, got) -> float:
    """V magnitude of 50 % completeness: a logistic fitted by maximum likelihood.

    ``P(m) = (1 - e) / (1 + exp((m - m50) / w))``: the lapse ``e`` (at most
    :data:`MAX_LAPSE`) takes the bright stars that are missed whatever their light (a
    saturated giant, a star on a satellite trail) off the curve's shape. It starts at the
    faintest 0.25 mag bin that is at least half complete.
    """
    from scipy.optimize import minimize

    mags, got = np.asarray(mags, float), np.asarray(got, bool)
    if got.sum() < 3 or (~got).sum() < 3:
        return math.nan

    def nll(p):
        m50, log_w, lapse_logit = p
        z = np.clip((mags - m50) / math.exp(log_w), -50, 50)
        lapse = MAX_LAPSE / (1.0 + math.exp(-lapse_logit))
        p_det = np.clip((1.0 - lapse) / (1.0 + np.exp(z)), 1e-12, 1 - 1e-12)
        return -float(np.sum(np.where(got, np.log(p_det), np.log1p(-p_det))))

    edges = np.arange(np.floor(mags.min()), mags.max() + 0.25, 0.25)
    half = [
        lo
        for lo in edges
        if np.count_nonzero((mags >= lo) & (mags < lo + 0.25)) >= 3
        and got[(mags >= lo) & (mags < lo + 0.25)].mean() >= 0.5
    ]
    start = [(max(half) + 0.125) if half else float(np.median(mags[got])), math.log(0.3), -3.0]
    res = minimize(nll, start, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-6})
    return float(res.x[0])


def _sigma2_model(mags, r2):
    """Fit ``s^2(m) = a + b F^-1 + c F^-2`` to squared residuals per axis (nonnegative)."""
    from scipy.optimize import nnls

    inv_f = 10.0 ** (0.4 * np.asarray(mags, float))
    design = np.column_stack([np.ones_like(inv_f), inv_f, inv_f**2])
    scale = np.max(design, axis=0)
    coef, _ = nnls(design / scale, np.asarray(r2, float) / 2.0)  # per axis: half the sum
    coef = coef / scale

    def sigma2(m):
        f = 10.0 ** (0.4 * np.asarray(m, float))
        return coef[0] + coef[1] * f + coef[2] * f**2

    return sigma2


def _twin(sensor, sol, image, catalog, rng, exposure_s=None):
    """Render the frame as the sensor predicts it, on the frame's own sky (module docstring)."""
    det = sensor.detector
    bg = estimate_background(np.asarray(image, dtype=np.float32), full_noise_map=False)
    sky_e = np.maximum(np.asarray(bg.level, dtype=np.float64) - det.bias_counts, 0.0)
    sky_e = np.broadcast_to(sky_e / det.gain_counts_per_e, image.shape)
    frame = render_frame(sensor, sol.rotation, catalog, noise=False, rng=rng, exposure_s=exposure_s)
    return apply_noise(frame.expected_e + sky_e, sensor, rng=rng, exposure_s=exposure_s)


def _quantity(measured: float, predicted: float) -> dict:
    ok = math.isfinite(measured) and math.isfinite(predicted) and predicted != 0
    return {
        "measured": measured if math.isfinite(measured) else None,
        "predicted": predicted if math.isfinite(predicted) else None,
        "ratio": measured / predicted if ok else None,
    }


def against(
    sensor,
    frames,
    *,
    catalog="hipparcos",
    exposures_s=None,
    draws: int = DRAWS,
    seed: int = 0,
) -> Against:
    """Hold the sensor's prediction against real frames (module docstring).

    Parameters
    ----------
    sensor : Sensor
        The camera (e.g. written by ``starsense characterize``).
    frames : sequence of path or ndarray
        Real frames of it (not those it was characterised on, for an honest check).
    catalog : Catalog or str
        The catalogue to identify and render with.
    exposures_s : float or sequence of float, optional
        The frames' exposure (one for all, or one a frame), s: the twins' stars and dark
        charge scale with it (default: the sensor's).
    draws : int
        Noise draws of each frame's twin.
    seed : int
        Root seed of the twins' noise.

    Returns
    -------
    Against

    Raises
    ------
    InputError
        No frames, a frame of another size than the sensor's, or no frame that solves.
    """
    frames = list(frames)
    if not frames:
        raise InputError("--against needs at least one frame")
    exps = [None] * len(frames)
    if exposures_s is not None:
        exps = [float(e) for e in np.atleast_1d(np.asarray(exposures_s, dtype=float))]
        exps = exps * len(frames) if len(exps) == 1 else exps
        if len(exps) != len(frames) or not all(math.isfinite(e) and e > 0 for e in exps):
            raise InputError(
                f"exposures_s: need one exposure > 0 s, or one a frame ({len(frames)}); got "
                f"{exposures_s!r}"
            )
    solver = Solver(sensor, catalog=catalog, extraction="robust")
    cat, _ = with_johnson_from_gaia(solver.catalog)  # the twins' stars and the limit need V
    gen = np.random.default_rng(seed)
    per, skipped = [], {}
    real = {"mags": [], "got": [], "m": [], "r2": []}
    twin = {"mags": [], "got": [], "m": [], "r2": []}
    for k, frame in enumerate(frames):
        name = str(frame) if not isinstance(frame, np.ndarray) else f"frame {k}"
        image = np.asarray(load_image(frame) if not isinstance(frame, np.ndarray) else frame)
        det = sensor.detector
        if image.shape != (det.rows, det.columns):
            raise InputError(
                f"{name}: {image.shape[1]} x {image.shape[0]} pixels, but sensor "
                f"{sensor.name!r} has {det.columns} x {det.rows}"
            )
        sol = solver(image)
        if not sol.solved:
            skipped[name] = sol.status
            continue
        for store, s in ((real, sol),):
            for key, val in zip(store, _statistics(s, sensor, cat), strict=True):
                store[key].append(val)
        counts = []
        for _ in range(draws):
            ts = solver(_twin(sensor, sol, image, cat, gen, exps[k]))
            counts.append((ts.n_detections, ts.n_matched if ts.solved else 0))
            if ts.solved:
                for key, val in zip(twin, _statistics(ts, sensor, cat), strict=True):
                    twin[key].append(val)
        det_p, mat_p = (float(np.mean(c)) for c in zip(*counts, strict=True))
        per.append(
            {
                "name": name,
                "detected": {"measured": sol.n_detections, "predicted": det_p},
                "matched": {"measured": sol.n_matched, "predicted": mat_p},
            }
        )
    if not per:
        raise InputError(f"--against: no frame solved with sensor {sensor.name!r}: {skipped}")
    return Against(per, skipped, _summary(per, real, twin))


def _summary(per, real, twin) -> dict:
    out = {}
    for key, label in (("matched", "matched_per_frame"), ("detected", "detected_per_frame")):
        m = float(np.mean([f[key]["measured"] for f in per]))
        p = float(np.mean([f[key]["predicted"] for f in per]))
        out[label] = _quantity(m, p)
    cat = np.concatenate
    out["limiting_magnitude"] = _quantity(
        _limit(cat(real["mags"]), cat(real["got"])), _limit(cat(twin["mags"]), cat(twin["got"]))
    )
    if twin["m"] and real["m"]:
        s2 = _sigma2_model(cat(twin["m"]), cat(twin["r2"]))
        rm, rr = cat(real["m"]), cat(real["r2"])
        tm, tr = cat(twin["m"]), cat(twin["r2"])
        measured = math.sqrt(float(np.mean(rr / (2.0 * s2(rm)))))
        predicted = math.sqrt(float(np.mean(tr / (2.0 * s2(tm)))))
        out["normalised_residual_rms"] = _quantity(measured, predicted)
    else:
        out["normalised_residual_rms"] = _quantity(math.nan, math.nan)
    return out
