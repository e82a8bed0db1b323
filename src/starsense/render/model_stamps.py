"""The expected-electron image of a frame drawn from the forward model's PSF (any shape).

For a sensor whose ``[psf]`` is not a Gaussian (Moffat, Airy, an empirical profile), each star
is drawn as the forward model draws it (:mod:`starsense.model.psf`): the pixel-integrated
profile at time nodes along its track (Gauss-Legendre, four per panel of two PSF sigmas of
each straight piece; one node for a star at rest), weighted by the time each piece takes, in
a box of the profile's radius around the track, clipped to the detector. The Gaussian keeps
its exact, faster path (:mod:`starsense.render.stamps`): both are the same model.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from starsense.model.psf import pixel_psf
from starsense.render.psf import Box

__all__ = ["model_expected_image"]

#: Gauss-Legendre nodes per panel of track (the model's quadrature, starsense.model.tracks)
_NODES_PER_PANEL = 4
#: node x pixel evaluations at once (bounds memory: ~8 bytes x 3 each)
_CHUNK = 2_000_000


def _track_nodes(verts: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return node positions (K,), (K,) and weights (K,) along a polyline of equal-time pieces."""
    if len(verts) < 2 or (np.allclose(verts[0], verts[-1]) and np.allclose(verts, verts[0])):
        return verts[:1, 0], verts[:1, 1], np.ones(1)
    t, w = np.polynomial.legendre.leggauss(_NODES_PER_PANEL)
    xs, ys, ws = [], [], []
    n_seg = len(verts) - 1
    for a, b in itertools.pairwise(verts):
        length = float(np.hypot(*(b - a)))
        panels = max(1, math.ceil(length / (2.0 * sigma)))
        u = ((np.arange(panels)[:, None] + 0.5 + 0.5 * t[None, :]) / panels).ravel()
        xs.append(a[0] + u * (b[0] - a[0]))
        ys.append(a[1] + u * (b[1] - a[1]))
        ws.append(np.tile(0.5 * w, panels) / panels / n_seg)
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(ws)


def _stamp(psf, xs, ys, ws, box: Box) -> np.ndarray:
    """Return a star's light per electron over ``box``: the sum over nodes of w_k P(pixel - p_k)."""
    out = np.zeros((box.row1 - box.row0, box.col1 - box.col0))
    step = max(1, _CHUNK // max(out.size, 1))
    for k0 in range(0, len(xs), step):
        sl = slice(k0, k0 + step)
        v = psf.grid(box.col0 - xs[sl], box.row0 - ys[sl], out.shape, gradient=False)
        out += np.tensordot(ws[sl], v, axes=1)
    return out


def model_expected_image(sensor, tracks, electrons: np.ndarray, *, sigmas: np.ndarray):
    """Return the float32 expected-electron image and the rendered stars' table.

    The same outputs as :func:`starsense.render.stamps.expected_image`, for any PSF shape.

    Parameters
    ----------
    sensor : Sensor
    tracks : Tracks
        The stars' tracks, px.
    electrons : ndarray, shape (N,)
        Each star's electrons over the exposure.
    sigmas : ndarray, shape (N,)
        Each star's PSF width (Gaussian-equivalent sigma), px.
    """
    det = sensor.detector
    image = np.zeros((det.rows, det.columns), dtype=np.float32)
    n = len(electrons)
    on_e, drawn, inside = np.zeros(n), np.zeros(n, bool), np.zeros(n, bool)
    valid = np.asarray(tracks.valid, bool)
    for i in np.flatnonzero(valid & (np.asarray(electrons) > 0)):
        psf = pixel_psf(sensor.psf, float(sigmas[i]))
        verts = np.asarray(tracks.vertices[i], dtype=float)
        xs, ys, ws = _track_nodes(verts, psf.sigma_px)
        full = Box.around(
            x_min=xs.min(), x_max=xs.max(), y_min=ys.min(), y_max=ys.max(), pad_px=psf.radius_px
        )
        box = full.clip(det.rows, det.columns)
        x, y = verts[:, 0], verts[:, 1]
        inside[i] = bool(
            np.all((x >= -0.5) & (x < det.columns - 0.5) & (y >= -0.5) & (y < det.rows - 0.5))
        )
        if box is None:
            continue
        stamp = float(electrons[i]) * _stamp(psf, xs, ys, ws, box)
        image[box.slices] += stamp.astype(np.float32)
        on_e[i], drawn[i] = float(stamp.sum()), True
    rendered = np.flatnonzero(drawn)
    nseg = np.array([len(tracks.vertices[i]) - 1 for i in rendered], dtype=np.int64)
    return image, (rendered.astype(np.intp), on_e[rendered], inside[rendered], nseg)
