"""A characterised camera as values with uncertainties, as a sensor, and as a sensor TOML.

:func:`measured_values` lists every value the frames told (:class:`~.values.Measured`) and
every one they could not (with the reason); :func:`camera_sensor` writes the told ones into the
base sensor; :func:`camera_toml` gives its TOML (:func:`starsense.sensor.dump.sensor_to_toml`)
with a ``[provenance]`` table: for each value its uncertainty, unit, frames, method and the
sensor field it was written to, and the fields kept from the base sensor. ``load_sensor``
accepts and ignores ``[provenance]``.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

from starsense.analysis.characterize.run import Characterisation
from starsense.analysis.characterize.values import Measured
from starsense.analysis.characterize.working import working_sensor
from starsense.sensor.dump import sensor_to_toml

__all__ = ["WRITTEN_TO", "camera_sensor", "camera_toml", "measured_values"]

#: the sensor field each measured value is written to
WRITTEN_TO = {
    "focal_length_px": "optics.focal_length_m",
    "principal_x_px": "optics.principal_offset_x_px",
    "principal_y_px": "optics.principal_offset_y_px",
    "k1": "optics.distortion_k1",
    "k2": "optics.distortion_k2",
    "p1": "optics.distortion_p1",
    "p2": "optics.distortion_p2",
    "distortion_residual_px": "optics.distortion_residual_px",
    "psf_sigma_px": "detector.psf_sigma_px",
    "psf_sigma_corner_px": "optics.psf_sigma_corner_px",
    "gain_counts_per_e": "detector.gain_counts_per_e",
    "read_noise_e": "detector.read_noise_e",
    "qe_mean": "detector.qe_mean",
    "hot_pixel_fraction": "detector.hot_pixel_fraction",
    "hot_pixel_e_s": "detector.hot_pixel_e_s",
}
#: a corner width this many sigmas from the centre's is a change across the field
SIGNIFICANT = 2.0


def _optics(ch: Characterisation, out: dict, frames: tuple) -> None:
    cal = ch.calibration
    v, s = cal.values, cal.sigmas
    how = f"joint fit of {cal.n_stars} matched stars' centroids (starsense calibrate)"
    for name, unit in (
        ("focal_length_px", "px"),
        ("principal_x_px", "px"),
        ("principal_y_px", "px"),
        ("k1", ""),
        ("k2", ""),
        ("p1", ""),
        ("p2", ""),
    ):
        if s[name] > 0:
            out[name] = Measured(v[name], s[name], unit, frames, how)
    floor, sigma, rms = ch.lens_residual
    if math.isfinite(floor):
        out["distortion_residual_px"] = Measured(
            floor,
            sigma,
            "px",
            frames,
            f"floor of the stars' residuals against magnitude (their rms {rms:.3g} px per axis "
            "includes their centroid noise, which falls with their light)",
        )
    else:
        out["distortion_residual_px"] = Measured(
            cal.rms_px_after,
            math.nan,
            "px",
            frames,
            "rms per axis about the calibrated camera (too few stars to part noise from lens)",
        )


def _psf(ch: Characterisation, out: dict, frames: tuple, not_told: dict) -> None:
    if math.isfinite(ch.psf_sigma_px):
        out["psf_sigma_px"] = Measured(
            ch.psf_sigma_px,
            ch.psf_sigma_err_px,
            "px",
            frames,
            "forward-model fit with a free width over each frame's matched stars",
        )
    else:
        not_told["psf_sigma_px"] = "the model fit did not converge on any frame"
    fp = ch.field_psf
    if not fp.told:
        not_told["psf_sigma_corner_px"] = (
            "too few matched stars in the field's zones to tell how the width changes"
        )
        return
    out["psf_sigma_centre_px"] = Measured(
        fp.centre_px, fp.centre_err_px, "px", frames, "zone widths, fit s0 + (s_corner - s0) u"
    )
    out["psf_sigma_corner_px"] = Measured(
        fp.corner_px, fp.corner_err_px, "px", frames, "zone widths, fit s0 + (s_corner - s0) u"
    )


def _photometry(ch: Characterisation, out: dict, frames: tuple, not_told: dict) -> None:
    z = ch.zero
    if z is None:
        not_told["zero_point"] = "fewer than three matched stars have a fitted flux"
        return
    unit = "counts/s" if z.per_second else "counts"
    out["zero_point"] = Measured(
        z.counts,
        z.counts_sigma,
        unit,
        frames,
        f"V = 0 star, slope -0.4 fixed, {z.n_stars} stars ({z.n_clipped} clipped)",
    )
    out["zero_point_scatter_mag"] = Measured(
        z.scatter_mag,
        z.scatter_mag / math.sqrt(2.0 * max(z.n_stars - 1, 1)),
        "mag",
        frames,
        "rms of the stars about the zero point",
    )
    if math.isfinite(z.slope):
        out["zero_point_slope"] = Measured(
            z.slope, z.slope_sigma, "", frames, "free slope of log10 flux vs V (linear: -0.4)"
        )
    if not z.per_second:
        not_told["throughput"] = "QE x transmission x gain needs the exposure (--exposure-s)"
        return
    thr, thr_s = z.throughput(ch.base.optics.aperture_m)
    place = "" if ch.base_given else " (the placeholder aperture: no --sensor)"
    out["throughput_counts_per_photon"] = Measured(
        thr, thr_s, "counts/photon", frames, "zero point / (Reed phi0 x aperture area)" + place
    )
    t = ch.base.optics.transmission
    if ch.transfer.told:
        g, gs = ch.transfer.gain_counts_per_e, ch.transfer.gain_sigma
        qe = thr / (g * t)
        qs = qe * math.hypot(thr_s / thr, gs / g)
        out["qe_mean"] = Measured(qe, qs, "", frames, "throughput / (gain x transmission)" + place)
    else:
        g = ch.gain_used
        out["qe_mean"] = Measured(
            thr / (g * t),
            thr_s / (g * t),
            "",
            frames,
            f"throughput / (the base gain {g:g} x transmission){place}: a star's counts are "
            "right, its electrons are not told (the gain is not)",
        )


def _noise(ch: Characterisation, out: dict, frames: tuple, not_told: dict) -> None:
    lv = np.array([n.level_counts for n in ch.noises])
    nz = np.array([n.noise_counts for n in ch.noises])
    spread = float(np.std(lv, ddof=1)) if lv.size > 1 else math.nan
    out["sky_level_counts"] = Measured(
        float(np.median(lv)), spread, "counts", frames, "median over frames (+- their spread)"
    )
    out["noise_counts"] = Measured(
        float(np.median(nz)),
        float(np.std(nz, ddof=1)) if nz.size > 1 else math.nan,
        "counts",
        frames,
        "per-pixel background noise, median over frames (+- their spread)",
    )
    tr = ch.transfer
    g = ch.gain_used
    if tr.told:
        out["gain_counts_per_e"] = Measured(
            tr.gain_counts_per_e,
            tr.gain_sigma,
            "counts/e",
            frames,
            f"photon transfer, {tr.n_boxes} boxes of {tr.n_frames} frames",
        )
        floor = max(tr.floor_counts2, 0.0)
        rn = math.sqrt(floor) / g
        rs = (tr.floor_sigma / (2.0 * math.sqrt(floor)) / g) if floor > 0 else math.nan
        out["read_noise_e"] = Measured(
            rn, rs, "e", frames, "photon transfer's floor at the bias (read noise, quantisation)"
        )
        return
    not_told["gain_counts_per_e"] = tr.reason
    reads = [
        working_sensor(ch.base, n, gain_counts_per_e=g).detector.read_noise_e for n in ch.noises
    ]
    out["read_noise_e"] = Measured(
        float(np.median(reads)),
        float(np.std(reads, ddof=1)) if len(reads) > 1 else math.nan,
        "e",
        frames,
        f"the background's per-pixel noise less the sky's shot noise at the base gain {g:g} "
        "counts/e, median over frames (+- their spread; the gain is not known, so read and "
        "shot noise are not told apart: a frame rendered with both has the measured noise)",
    )


def _hot(ch: Characterisation, out: dict, frames: tuple, not_told: dict) -> None:
    h = ch.hot
    n_pix = h.map.size
    for name, frac in (
        ("hot_pixel_fraction", h.hot_fraction),
        ("warm_pixel_fraction", h.warm_fraction),
    ):
        count = frac * n_pix
        out[name] = Measured(
            frac,
            math.sqrt(max(count, 1.0)) / n_pix,
            "",
            frames,
            "isolated excess in every frame" + (f" ({h.note})" if h.note else ""),
        )
    if h.excess_counts.size and ch.exposures_s is not None:
        t = float(np.median(ch.exposures_s))
        rate = float(np.median(h.excess_counts)) / ch.gain_used / t
        spread = float(np.std(h.excess_counts)) / ch.gain_used / t / math.sqrt(h.excess_counts.size)
        out["hot_pixel_e_s"] = Measured(rate, spread, "e/s", frames, "median hot-pixel excess")
    elif h.excess_counts.size:
        not_told["hot_pixel_e_s"] = "a hot pixel's dark current needs the exposure"


def measured_values(ch: Characterisation) -> tuple[dict, dict]:
    """Return the values the frames told (name -> Measured) and those they did not (-> why)."""
    frames = tuple(ch.names)
    out, not_told = {}, {}
    _optics(ch, out, frames)
    _psf(ch, out, frames, not_told)
    _photometry(ch, out, frames, not_told)
    _noise(ch, out, frames, not_told)
    _hot(ch, out, frames, not_told)
    return out, not_told


def _psf_varies(values: dict) -> bool:
    """Return whether the corners' PSF width is more than SIGNIFICANT sigma from the centre's.

    Then the centre's and the corners' widths are written; else the width over the whole field,
    the same everywhere (``optics.psf_sigma_corner_px = 0``).
    """
    centre, corner = values.get("psf_sigma_centre_px"), values.get("psf_sigma_corner_px")
    return (
        centre is not None
        and corner is not None
        and abs(corner.value - centre.value)
        > SIGNIFICANT * math.hypot(corner.uncertainty, centre.uncertainty)
    )


def _written_to(values: dict) -> dict:
    """Return each measured value's sensor field as :func:`camera_sensor` writes it ("": none)."""
    out = {key: WRITTEN_TO.get(key, "") for key in values}
    if "psf_sigma_corner_px" in out:  # the field's width alone, or the centre's and corners'
        varies = _psf_varies(values)
        out["psf_sigma_corner_px"] = "optics.psf_sigma_corner_px" if varies else ""
        out["psf_sigma_centre_px"] = "detector.psf_sigma_px" if varies else ""
        if varies and "psf_sigma_px" in out:
            out["psf_sigma_px"] = ""
    return out


def camera_sensor(ch: Characterisation, name: str = "camera"):
    """Return the base sensor with the measured values written in (see :data:`WRITTEN_TO`)."""
    values, _ = measured_values(ch)
    cal = ch.calibration.sensor
    optics, det = cal.optics, cal.detector
    o, d = {}, {}
    width = values.get("psf_sigma_px")
    centre, corner = values.get("psf_sigma_centre_px"), values.get("psf_sigma_corner_px")
    if _psf_varies(values):
        d["psf_sigma_px"], o["psf_sigma_corner_px"] = centre.value, max(corner.value, 0.0)
    elif width is not None:
        d["psf_sigma_px"], o["psf_sigma_corner_px"] = width.value, 0.0
    o["distortion_residual_px"] = values["distortion_residual_px"].value
    for key in ("gain_counts_per_e", "read_noise_e", "hot_pixel_fraction", "hot_pixel_e_s"):
        if key in values and values[key].value > 0:
            d[key] = values[key].value
    if "qe_mean" in values and 0 < values["qe_mean"].value <= 1:
        d["qe_mean"] = values["qe_mean"].value
    exposure = ch.exposures_s[0] if ch.exposures_s and len(set(ch.exposures_s)) == 1 else None
    o = {k: float(v) for k, v in o.items()}  # plain floats: the TOML writer's repr
    d = {k: float(v) for k, v in d.items()}
    return cal.with_(
        name=name,
        optics=dataclasses.replace(optics, **o),
        detector=dataclasses.replace(det, **d),
        exposure_s=exposure if exposure is not None else cal.exposure_s,
    )


def _toml_value(v) -> str:
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else "nan"
    if isinstance(v, str):
        return json.dumps(v)
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


def camera_toml(ch: Characterisation, name: str = "camera") -> str:
    """Return the characterised sensor's TOML, with its ``[provenance]`` table (docstring)."""
    sensor = camera_sensor(ch, name)
    values, not_told = measured_values(ch)
    cal = ch.calibration
    header = (
        f"starsense characterize: {len(ch.frames)} frame(s), {cal.n_stars} matched stars\n"
        f"base sensor: {ch.base.name if ch.base_given else 'none (nominal placeholders)'}\n"
        "measured values, their uncertainties and frames: [provenance] at the end"
    )
    text = sensor_to_toml(sensor, header)
    targets = _written_to(values)
    written = set(targets.values()) - {""}
    if "psf_sigma_centre_px" in values:
        written.add("detector.psf_sigma_px")
        written.add("optics.psf_sigma_corner_px")  # 0 (uniform) or the corners' width
    kept = []
    for section in ("optics", "detector"):
        for f in dataclasses.fields(getattr(sensor, section)):
            if f"{section}.{f.name}" not in written:
                kept.append(f"{section}.{f.name}")
    lines = [
        "",
        "[provenance]",
        'command = "starsense characterize"',
        f"frames = {_toml_value(list(ch.names))}",
        f"base = {_toml_value(ch.base.name if ch.base_given else '')}",
        f"kept_from_base = {_toml_value(kept)}",
    ]
    if not_told:
        lines += ["", "[provenance.not_told]"]
        lines += [f"{k} = {_toml_value(v)}" for k, v in not_told.items()]
    for key, m in values.items():
        lines += [
            "",
            f"[provenance.measured.{key}]",
            f"value = {_toml_value(float(m.value))}",
            f"uncertainty = {_toml_value(float(m.uncertainty))}",
            f"unit = {_toml_value(m.unit)}",
            f"method = {_toml_value(m.method)}",
            f"written_to = {_toml_value(targets[key])}",
        ]
    return text + "\n".join(lines) + "\n"
