"""Rendered frame sequences: a constant body rate, frames at a fixed interval, each with its truth.

The attitude of frame ``k`` (mid-exposure, time ``t_k = k dt``) follows the convention of
:mod:`starsense.render.scene` for a constant camera-frame rate ``w``::

    A_k = R(-w t_k) A_0

(``R`` the rotation by that rotation vector), so that within each exposure the stars move as
:func:`~starsense.render.scene.render_frame` renders them and from frame to frame as the same
rotation carries on. Each frame gets its own noise stream, a child of the root seed
(``numpy.random.SeedSequence(seed).spawn``), recorded in its truth with its time.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._validate import check_int, positive_float
from starsense.errors import InputError
from starsense.geometry.apparent import parse_time
from starsense.render.frame import Frame
from starsense.render.scene import render_frame
from starsense.render.tracks import check_rate

__all__ = ["frame_seeds", "propagate_attitude", "render_sequence", "sequence_paths"]


def propagate_attitude(attitude: Rotation, rate_rad_s, time_s) -> Rotation:
    """Return the attitude after ``time_s`` at the constant camera-frame rate ``rate_rad_s``.

    ``A(t) = R(-w t) A(0)``: the convention of :mod:`starsense.render.scene`.

    Parameters
    ----------
    attitude : Rotation
        Attitude at t = 0, ICRS -> camera (single).
    rate_rad_s : array_like, shape (3,)
        Body rate in the camera frame, rad/s.
    time_s : float or array_like, shape (K,)
        Time(s) since t = 0, s.

    Returns
    -------
    Rotation
        Single for a scalar time, else a batch of K.
    """
    w = check_rate(rate_rad_s)
    t = np.asarray(time_s, dtype=float)
    return Rotation.from_rotvec(-np.multiply.outer(t, w)) * attitude


def frame_seeds(seed: int, n_frames: int) -> list[int]:
    """Return ``n_frames`` child seeds of a root seed (``SeedSequence(seed).spawn``), one per frame.

    Parameters
    ----------
    seed : int
        Root seed (>= 0).
    n_frames : int
        Frames.

    Returns
    -------
    list of int
        63-bit seeds (they fit a FITS integer keyword).
    """
    seed = check_int(seed, "seed", 0)
    children = np.random.SeedSequence(seed).spawn(check_int(n_frames, "n_frames", 1))
    return [int(c.generate_state(1, np.uint64)[0] >> np.uint64(1)) for c in children]


def sequence_paths(out: str | Path, n_frames: int) -> list[Path]:
    """Return the frame paths of a sequence: ``DIR/frame.tiff`` -> ``DIR/frame_000.tiff`` ...

    Parameters
    ----------
    out : path-like
        The pattern: its stem gets ``_000``, ``_001`` ... (at least three digits).
    n_frames : int
        Frames.

    Returns
    -------
    list of Path
    """
    out = Path(out)
    width = max(3, len(str(n_frames - 1)))
    return [out.with_name(f"{out.stem}_{k:0{width}d}{out.suffix}") for k in range(n_frames)]


def render_sequence(
    sensor,
    rotation: Rotation,
    catalog=None,
    *,
    n_frames: int,
    interval_s: float,
    rate_rad_s=(0.0, 0.0, 0.0),
    seed: int = 0,
    **kwargs,
) -> Iterator[Frame]:
    """Render ``n_frames`` frames at a constant body rate, one every ``interval_s``.

    Parameters
    ----------
    sensor : Sensor
    rotation : Rotation
        Mid-exposure attitude of the first frame, ICRS -> camera.
    catalog : Catalog or str, optional
        The stars (as in :func:`~starsense.render.scene.render_frame`; default the bundled
        Hipparcos).
    n_frames : int
        Frames (>= 1).
    interval_s : float
        Time between consecutive mid-exposures, s (> 0; at least the exposure).
    rate_rad_s : array_like, shape (3,)
        Constant body rate in the camera frame, rad/s.
    seed : int
        Root seed; frame ``k`` uses child seed ``frame_seeds(seed, n_frames)[k]``.
    **kwargs
        Passed to :func:`~starsense.render.scene.render_frame` (model, max_mag, noise, ...);
        ``obs_time`` is the time of the first frame, frame ``k`` is taken ``k * interval_s``
        later.

    Yields
    ------
    Frame
        Each with ``truth.time_s = k * interval_s`` and its own seed.

    Raises
    ------
    InputError
        Bad count, interval (not > 0, or shorter than the exposure), rate or seed.
    """
    n = check_int(n_frames, "n_frames", 1)
    dt = positive_float(interval_s, "interval_s")
    te = sensor.exposure_or(kwargs.get("exposure_s"))
    if dt < te:
        raise InputError(
            f"interval_s = {dt:g} s is shorter than the exposure ({te:g} s): frames would overlap"
        )
    w = check_rate(rate_rad_s)
    if "rng" in kwargs:
        raise InputError("render_sequence takes seed=, not rng= (each frame gets a child seed)")
    seeds = frame_seeds(seed, n)
    start = kwargs.pop("obs_time", None)
    if start is not None:
        from astropy.time import TimeDelta

        start = parse_time(start, "obs_time")
    for k in range(n):
        t = k * dt
        att = propagate_attitude(rotation, w, t)
        if start is not None:
            kwargs["obs_time"] = start + TimeDelta(t, format="sec")
        frame = render_frame(sensor, att, catalog, rate_rad_s=w, rng=seeds[k], **kwargs)
        truth = dataclasses.replace(frame.truth, time_s=t)
        yield dataclasses.replace(frame, truth=truth)
