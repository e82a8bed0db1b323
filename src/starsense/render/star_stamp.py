"""One star on the detector, static or smeared: the stamp the slew analysis and the tests draw."""

from __future__ import annotations

import numpy as np

from starsense._validate import check_scalar, finite_array
from starsense.errors import InputError
from starsense.render.noise import apply_noise, quantise
from starsense.render.scene import check_on_detector
from starsense.render.smear import pad_sigma_for, polyline_expected
from starsense.render.tracks import check_rate, star_tracks

__all__ = ["render_star_stamp"]


def _sigma(sensor) -> float:
    return float(sensor.detector.psf_sigma_px)


def render_star_stamp(
    sensor,
    electrons: float,
    *,
    rate_rad_s=None,
    streak_px=None,
    offset_px=(0.0, 0.0),
    rng=None,
    noise: bool = True,
    exposure_s: float | None = None,
    pad_sigma: float | None = None,
    method: str = "track",
) -> np.ndarray:
    """Render one star at the boresight, static or smeared: the slew analysis' image, counts.

    The star's mid-exposure centroid is the principal point plus ``offset_px``. Its motion is
    given either by a body rate (exact rotation, arcs sub-stepped, as in :func:`render_frame`)
    or directly by a straight streak ``(dx, dy)`` px centred on that point; neither means static.

    Parameters
    ----------
    sensor : Sensor
    electrons : float
        Expected photo-electrons of the star over the exposure (>= 0).
    rate_rad_s : array_like, shape (3,), optional
        Body rate (camera frame), rad/s.
    streak_px : (float, float), optional
        Streak displacement from start to end, px.
    offset_px : (float, float)
        Sub-pixel (or any) offset of the mid-exposure centroid from the principal point, px.
    rng : None, int or Generator
        Noise source (see :func:`starsense.render.noise.as_generator`).
    noise : bool
        Add shot and read noise (else the quantised expected image).
    exposure_s : float, optional
        Exposure for the rate, s (default ``sensor.exposure_s``).
    pad_sigma : float, optional
        Stamp half-width around the track in sigma (default 5-8 by brightness,
        :func:`~starsense.render.smear.pad_sigma_for`).
    method : {"track", "closed-form"}

    Returns
    -------
    ndarray, uint16 or uint32
        The stamp's counts (the whole box around the track; background pixels carry read noise
        only).

    Raises
    ------
    InputError
        Both ``rate_rad_s`` and ``streak_px`` given; bad rate or exposure; the track leaves the
        detector.
    """
    e = check_scalar(electrons, "electrons", 0.0)
    if rate_rad_s is not None and streak_px is not None:
        raise InputError("give rate_rad_s or streak_px, not both")
    te = sensor.exposure_or(exposure_s)
    ox, oy = (float(v) for v in offset_px)
    cx, cy = sensor.principal_point_px
    x, y = cx + ox, cy + oy
    if streak_px is not None:
        dx, dy = (float(v) for v in finite_array(streak_px, "streak_px"))
        xs = np.array([x - dx / 2, x + dx / 2])
        ys = np.array([y - dy / 2, y + dy / 2])
        what = f"streak of ({dx:g}, {dy:g}) px"
    else:
        w = check_rate((0.0, 0.0, 0.0) if rate_rad_s is None else rate_rad_s)
        tracks = star_tracks(sensor, sensor.unproject([x], [y]), rate_rad_s=w, exposure_s=te)
        xs, ys = tracks.vertices[0][:, 0], tracks.vertices[0][:, 1]
        what = f"star at rate {w.tolist()} rad/s over {te:g} s"
    check_on_detector(sensor, np.append(xs, x), np.append(ys, y), what=what)
    pad = float(pad_sigma_for(e, _sigma(sensor))) if pad_sigma is None else float(pad_sigma)
    stamp, _ = polyline_expected(
        xs, ys, sigma_px=_sigma(sensor), electrons=e, pad_sigma=pad, method=method
    )
    if noise:
        return apply_noise(stamp, sensor, rng=rng, exposure_s=te)
    return quantise(stamp, sensor)
