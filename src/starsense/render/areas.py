"""Frames of attitude-determination areas (Lin et al. 2024): render and detect per area.

A camera that reads stars only in some focal-plane areas (:mod:`starsense.geometry.areas`) is
simulated on a *focal-plane sensor*: the same optics and pixels, with a detector grown to cover
every area. Pixels outside the areas hold no detector: they read the bias level, without noise,
so nothing is detected there and a star that straddles an area's edge is cut as the real
detector would cut it. Detection runs on that image with the sensor's own logic and tags each
detection with the area of its centroid.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from starsense.errors import InputError
from starsense.geometry.projection import vectors_to_tangent
from starsense.render.scene import render_frame

__all__ = ["AreaFrame", "area_pixel_index", "focal_plane_sensor", "render_areas"]


def _layout(sensor):
    layout = getattr(sensor, "attitude_areas", None)
    if layout is None:
        raise InputError(f"sensor {sensor.name!r} defines no [attitude_areas]")
    return layout


def focal_plane_sensor(sensor):
    """Return the sensor with a square detector grown to cover all its attitude areas.

    Same focal length, pixel pitch, noise and detection logic; ``columns = rows`` = twice the
    largest distance of an area vertex from the optical axis, in pixels, plus a margin of 8.

    Parameters
    ----------
    sensor : Sensor
        With ``attitude_areas`` (:class:`starsense.geometry.areas.AreaLayout`).

    Returns
    -------
    Sensor
        The focal-plane sensor, named ``"<name> (focal plane)"``.
    """
    layout = _layout(sensor)
    reach = max(float(np.hypot(*a.vertices.T).max()) for a in layout.areas)
    half = math.ceil(reach * sensor.focal_length_px) + 4
    if 2 * half > 40_000:
        raise InputError(
            f"the attitude-determination areas of {sensor.name!r} reach {2 * half} pixels across; "
            "too large to render as one frame (limit 40,000)"
        )
    det = dataclasses.replace(sensor.detector, columns=2 * half, rows=2 * half)
    return sensor.with_(detector=det, name=f"{sensor.name} (focal plane)")


def area_pixel_index(fp_sensor) -> NDArray[np.int8]:
    """Return the area number (1-based, 0 = no detector) of every pixel of a sensor.

    A pixel belongs to the area holding its centre (pixel-centre convention, distortion
    included through :meth:`Sensor.unproject`).

    Parameters
    ----------
    fp_sensor : Sensor
        A focal-plane sensor (:func:`focal_plane_sensor`).

    Returns
    -------
    ndarray of int8, shape (rows, columns)
    """
    layout = _layout(fp_sensor)
    rows, cols = fp_sensor.detector.rows, fp_sensor.detector.columns
    if not fp_sensor.optics.has_distortion:
        # pinhole: the pixel centres are a regular grid of the tangent plane (scanline fill)
        cx, cy = fp_sensor.principal_point_px
        f = fp_sensor.focal_length_px
        xs = (np.arange(cols) - cx) / f
        ys = (np.arange(rows) - cy) / f
        return layout.index_grid(xs, ys).astype(np.int8)
    yy, xx = np.mgrid[0:rows, 0:cols]
    xy = vectors_to_tangent(fp_sensor.unproject(xx.ravel(), yy.ravel()))
    return layout.index(xy).astype(np.int8).reshape(rows, cols)


@dataclass(frozen=True, eq=False)
class AreaFrame:
    """A rendered frame of the attitude-determination areas.

    Attributes
    ----------
    frame : Frame
        On ``sensor``; pixels outside the areas read the bias level.
    sensor : Sensor
        The focal-plane sensor (:func:`focal_plane_sensor`).
    pixel_area : ndarray of int8, shape (rows, columns)
        Area number of each pixel, 0 outside.
    star_area : ndarray of int, shape (N,)
        Area number of each rendered star's mid-exposure centroid (``frame.truth.stars``).
    """

    frame: object
    sensor: object
    pixel_area: NDArray[np.int8]
    star_area: NDArray[np.int_]


def render_areas(sensor, rotation, catalog=None, **kwargs) -> AreaFrame:
    """Render what the attitude-determination areas of ``sensor`` see.

    Parameters
    ----------
    sensor : Sensor
        With ``attitude_areas``.
    rotation : Rotation
        The attitude, ICRS -> camera.
    catalog : Catalog or str, optional
        The stars (as in :func:`starsense.render.render_frame`; default the bundled Hipparcos).
    **kwargs
        Passed to :func:`starsense.render.render_frame` (rate, model, band, max_mag, rng, ...).

    Returns
    -------
    AreaFrame
        The frame on the focal-plane sensor, pixels outside the areas at the bias level.
    """
    fp = focal_plane_sensor(sensor)
    frame = render_frame(fp, rotation, catalog, **kwargs)
    pixel_area = area_pixel_index(fp)
    outside = pixel_area == 0
    bias = np.asarray(round(fp.detector.bias_counts)).astype(frame.image.dtype)
    frame.image[outside] = bias
    if frame.expected_e is not None:
        frame.expected_e[outside] = 0.0
    st = frame.truth.stars
    xi = np.clip(np.round(st.x_mid).astype(int), 0, fp.detector.columns - 1)
    yi = np.clip(np.round(st.y_mid).astype(int), 0, fp.detector.rows - 1)
    on = (st.x_mid >= -0.5) & (st.x_mid < fp.detector.columns - 0.5)
    on &= (st.y_mid >= -0.5) & (st.y_mid < fp.detector.rows - 0.5)
    star_area = np.where(on, pixel_area[yi, xi], 0).astype(int)
    return AreaFrame(frame, fp, pixel_area, star_area)
