"""Rendered frames: catalogue + attitude + body rate -> detector counts and their truth.

Modules, in the order light passes through them:

* :mod:`~starsense.render.psf` -- the static Gaussian PSF integrated exactly over pixels (eq. 9);
* :mod:`~starsense.render.smear` -- the smeared PSF of a moving star (eqs. 13-22);
* :mod:`~starsense.render.tracks` -- star tracks from the exact rotation of the camera (eq. 10),
  arcs by sub-stepping;
* :mod:`~starsense.render.noise` -- shot and read noise, gain, bias, quantisation (sec. 3.1);
* :mod:`~starsense.render.scene` -- :func:`render_frame`; :mod:`~starsense.render.star_stamp`
  -- :func:`render_star_stamp`;
* :mod:`~starsense.render.frame` -- :class:`Frame` and its truth;
* :mod:`~starsense.render.io` -- :func:`write_frame` (TIFF / PNG / FITS + JSON truth).

Equation numbers are those of Dzamba & Enright 2014, Sensors 14, 3939.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: the package's names -> the module that defines each. Loaded on first use: a module that
#: needs one kernel (the solver's blends: render.smear) does not import the renderer, its
#: noise and its writers (a tenth of ``starsense solve``'s start-up)
_EXPORTS = {
    "Frame": "frame",
    "FrameTruth": "frame",
    "StarTruth": "frame",
    "write_frame": "io",
    "write_frames": "io",
    "apply_noise": "noise",
    "as_generator": "noise",
    "quantise": "noise",
    "Box": "psf",
    "gaussian_stamp": "psf",
    "check_on_detector": "scene",
    "render_frame": "scene",
    "render_star_stamp": "star_stamp",
    "gauss_legendre_order": "smear",
    "polyline_expected": "smear",
    "smear_intensity": "smear",
    "streak_stamp_expected": "smear",
    "Tracks": "tracks",
    "star_tracks": "tracks",
}

if TYPE_CHECKING:
    from starsense.render.frame import Frame, FrameTruth, StarTruth
    from starsense.render.io import write_frame, write_frames
    from starsense.render.noise import apply_noise, as_generator, quantise
    from starsense.render.psf import Box, gaussian_stamp
    from starsense.render.scene import check_on_detector, render_frame
    from starsense.render.smear import (
        gauss_legendre_order,
        polyline_expected,
        smear_intensity,
        streak_stamp_expected,
    )
    from starsense.render.star_stamp import render_star_stamp
    from starsense.render.tracks import Tracks, star_tracks


def __getattr__(name: str) -> Any:
    """Return a name of the package, imported from its module on first use."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f"starsense.render.{_EXPORTS[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})


__all__ = [
    "Box",
    "Frame",
    "FrameTruth",
    "StarTruth",
    "Tracks",
    "apply_noise",
    "as_generator",
    "check_on_detector",
    "gauss_legendre_order",
    "gaussian_stamp",
    "polyline_expected",
    "quantise",
    "render_frame",
    "render_star_stamp",
    "smear_intensity",
    "star_tracks",
    "streak_stamp_expected",
    "write_frame",
    "write_frames",
]
