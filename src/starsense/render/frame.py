"""A rendered frame and its truth: the image, the expected electrons and what they were made from.

:class:`Frame` holds the digital counts, the noiseless expected electrons and a
:class:`FrameTruth`: the sensor, catalogue, attitude, rate, exposure, noise seed and models,
and a :class:`StarTruth` table with one row per rendered star. ``Frame.truth_dict()`` is the
JSON written beside the image (:func:`starsense.render.io.write_frame`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["Frame", "FrameTruth", "StarTruth"]


def _json_list(a: np.ndarray) -> list:
    """Column -> JSON-able list (NaN -> None)."""
    if a.dtype == bool:
        return [bool(v) for v in a]
    if np.issubdtype(a.dtype, np.integer):
        return [int(v) for v in a]
    return [float(v) if math.isfinite(v) else None for v in a.tolist()]


@dataclass(frozen=True, eq=False)
class StarTruth:
    """The rendered stars, one row per star (columns of shape (N,)).

    Attributes
    ----------
    ids : int64
        Catalogue identifiers.
    mag : float64
        Catalogue magnitude in the band used (``FrameTruth.band``).
    colour_index : float64
        Colour index used by the black-body model (NaN for the other models).
    electrons : float64
        Expected photo-electrons of the star over the exposure.
    electrons_on_detector : float64
        The part of ``electrons`` that falls on detector pixels (noiseless; less than
        ``electrons`` for stars at or beyond the edges, and by < 1e-6 for the rest: the PSF
        is rendered to 5-8 sigma).
    x_start, y_start, x_mid, y_mid, x_end, y_end : float64
        Centroid at t = 0, t_e / 2 and t_e, px (pixel-centre convention).
    on_detector : bool
        True if the whole centroid track lies on the detector (x in [-0.5, columns - 0.5),
        y in [-0.5, rows - 0.5)).
    n_segments : int64
        Straight segments the track was sub-stepped into.
    """

    ids: np.ndarray
    mag: np.ndarray
    colour_index: np.ndarray
    electrons: np.ndarray
    electrons_on_detector: np.ndarray
    x_start: np.ndarray
    y_start: np.ndarray
    x_mid: np.ndarray
    y_mid: np.ndarray
    x_end: np.ndarray
    y_end: np.ndarray
    on_detector: np.ndarray
    n_segments: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    @classmethod
    def empty(cls) -> StarTruth:
        """Return a table of no stars."""
        f = np.zeros(0)
        return cls(
            ids=np.zeros(0, np.int64),
            mag=f,
            colour_index=f,
            electrons=f,
            electrons_on_detector=f,
            x_start=f,
            y_start=f,
            x_mid=f,
            y_mid=f,
            x_end=f,
            y_end=f,
            on_detector=np.zeros(0, bool),
            n_segments=np.zeros(0, np.int64),
        )

    def to_dict(self) -> dict[str, list]:
        """Columns as JSON-able lists (NaN -> None)."""
        return {f.name: _json_list(getattr(self, f.name)) for f in dataclasses.fields(self)}


@dataclass(frozen=True, eq=False)
class FrameTruth:
    """Everything a rendered frame was made from.

    Attributes
    ----------
    sensor : str
        Sensor name.
    catalog : str
        Catalogue name.
    attitude : Rotation
        Mid-exposure attitude (ICRS -> camera).
    ra_rad, dec_rad, roll_rad : float
        The same as boresight RA, Dec and roll (:mod:`starsense.geometry.attitude`).
    rate_rad_s : tuple of 3 float
        Body rate in the camera frame, rad/s.
    exposure_s : float
    seed : int or None
        Seed of the noise generator (None when the caller passed a Generator).
    model, band : str
        Sensitivity model and the catalogue band of its magnitudes.
    colour : str or None
        Colour system of the black-body model (None for reed / liebe).
    max_mag : float or None
        Faint limit applied to the catalogue.
    noise : bool
        Whether shot and read noise were added.
    method : str
        Pixel quadrature of the smeared PSF.
    stars : StarTruth
    apparent : dict or None
        The apparent places the stars were rendered at (time, observer speed;
        :meth:`starsense.catalog.apparent.ApparentPlaces.to_dict`); None for catalogue places.
    time_s : float or None
        Mid-exposure time of the frame in its sequence, s (None for a lone frame;
        :func:`starsense.render.sequence.render_sequence`).
    """

    sensor: str
    catalog: str
    attitude: Rotation
    ra_rad: float
    dec_rad: float
    roll_rad: float
    rate_rad_s: tuple[float, float, float]
    exposure_s: float
    seed: int | None
    model: str
    band: str
    colour: str | None
    max_mag: float | None
    noise: bool
    method: str
    stars: StarTruth
    apparent: dict | None = None
    time_s: float | None = None

    def to_dict(self) -> dict:
        """JSON-able dictionary (angles also in degrees, quaternion scalar-last)."""
        return {
            "sensor": self.sensor,
            "catalog": self.catalog,
            "attitude": {
                "ra_rad": self.ra_rad,
                "dec_rad": self.dec_rad,
                "roll_rad": self.roll_rad,
                "ra_deg": math.degrees(self.ra_rad),
                "dec_deg": math.degrees(self.dec_rad),
                "roll_deg": math.degrees(self.roll_rad),
                "quaternion_xyzw": [float(q) for q in self.attitude.as_quat()],
                "epoch": "mid-exposure",
            },
            "rate_rad_s": list(self.rate_rad_s),
            "exposure_s": self.exposure_s,
            "seed": self.seed,
            "model": self.model,
            "band": self.band,
            "colour": self.colour,
            "max_mag": self.max_mag,
            "noise": self.noise,
            "method": self.method,
            "apparent_places": self.apparent,
            "time_s": self.time_s,
            "n_stars": len(self.stars),
            "stars": self.stars.to_dict(),
        }


@dataclass(frozen=True, eq=False)
class Frame:
    """A rendered frame (:func:`starsense.render.render_frame`): the image and its truth.

    Attributes
    ----------
    image : ndarray, shape (rows, columns), uint16 (bits <= 16) or uint32
        Digital counts.
    expected_e : ndarray, shape (rows, columns), float32, or None
        Noiseless expected photo-electrons per pixel (stars only: no dark current, no bias);
        None when rendered with ``keep_expected=False`` (saves 4 bytes per pixel, 20 MB for
        the ST-16).
    truth : FrameTruth
        What was rendered: sensor and catalogue names, attitude (``truth.attitude``, a
        Rotation, and ``ra_rad`` / ``dec_rad`` / ``roll_rad``), rate, exposure, the seed of the
        noise, and one row per rendered star (``truth.stars``: ids, magnitudes, electrons,
        pixel tracks), so every later stage can be scored.
    """

    image: np.ndarray
    expected_e: np.ndarray | None
    truth: FrameTruth

    def truth_dict(self) -> dict:
        """Return the truth as a JSON-able dictionary."""
        return self.truth.to_dict()
