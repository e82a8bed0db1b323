"""Rendered frames: catalogue + attitude + body rate -> detector image and its truth.

:func:`render_frame` follows Dzamba & Enright 2014, sec. 3.1, over a whole detector:

1. select the catalogue stars that can reach the detector during the exposure (a cone around
   the boresight: the field's enclosing radius, plus the angle the sky turns in half an
   exposure, plus the PSF margin);
2. electrons of each star from its magnitude (eqs. 6 / 8, or the colour-aware black body) via
   :class:`~starsense.photometry.sensitivity.Sensitivity`;
3. each star's track from the exact rotation of the camera during the exposure, sub-stepped into
   straight segments (:func:`~starsense.render.smear.star_tracks`), rendered as a smeared
   Gaussian (eqs. 9-22) integrated over pixel areas, only in a box around the track;
4. shot noise, read noise, gain, 12-bit (or other) quantisation
   (:mod:`starsense.render.noise`).

Times: ``attitude`` is the attitude at **mid-exposure**; with the body rate ``w`` (camera
frame, rad/s, constant) the attitude at time ``t`` in ``[0, t_e]`` is
``A(t) = R(-w (t - t_e/2)) A`` (``R`` the rotation by that rotation vector), so a star's camera
direction is ``b(t) = R(-w (t - t_e/2)) A v``. The truth's ``x_mid, y_mid`` are
``sensor.project(A v)``, which is what an attitude solution of the frame should reproduce.

Catalogue positions are used at the catalogue's epoch: call ``catalog.propagate(epoch)`` first
for another date.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from starsense.errors import InputError
from starsense.geometry.attitude import radec_roll_from_attitude
from starsense.render.noise import apply_noise, as_generator, quantise
from starsense.render.psf import Box
from starsense.render.smear import (
    METHODS,
    check_exposure,
    check_rate,
    pad_sigma_for,
    polyline_expected,
    star_tracks,
    streak_stamp_expected,
)

__all__ = [
    "Frame",
    "FrameTruth",
    "StarTruth",
    "check_on_detector",
    "render_frame",
    "render_star_stamp",
    "streak_stamp_expected",
]

_MODELS = ("reed", "liebe", "blackbody")


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
            "n_stars": len(self.stars),
            "stars": self.stars.to_dict(),
        }


@dataclass(frozen=True, eq=False)
class Frame:
    """A rendered frame.

    Attributes
    ----------
    image : ndarray, shape (rows, columns), uint16 (bits <= 16) or uint32
        Digital counts.
    expected_e : ndarray, shape (rows, columns), float32, or None
        Noiseless expected photo-electrons per pixel (stars only: no dark current, no bias);
        None when rendered with ``keep_expected=False`` (saves 4 bytes per pixel, 20 MB for
        the ST-16).
    truth : FrameTruth
    """

    image: np.ndarray
    expected_e: np.ndarray | None
    truth: FrameTruth

    def truth_dict(self) -> dict:
        """The truth as a JSON-able dictionary."""
        return self.truth.to_dict()


# ---------------------------------------------------------------------------------------------


def check_on_detector(sensor, x, y, *, what: str = "star track") -> None:
    """Raise InputError unless every point (x, y) lies on the detector.

    The detector covers x in [-0.5, columns - 0.5) and y in [-0.5, rows - 0.5).

    Parameters
    ----------
    sensor : Sensor
    x, y : array_like
        Points, px.
    what : str
        Name used in the message.
    """
    det = sensor.detector
    xa = np.atleast_1d(np.asarray(x, dtype=float))
    ya = np.atleast_1d(np.asarray(y, dtype=float))
    inside = (xa >= -0.5) & (xa < det.columns - 0.5) & (ya >= -0.5) & (ya < det.rows - 0.5)
    if not np.all(inside):
        i = int(np.argmin(inside))
        raise InputError(
            f"{what} leaves the detector: point (x={xa[i]:.2f}, y={ya[i]:.2f}) px is outside "
            f"x in [-0.5, {det.columns - 0.5}), y in [-0.5, {det.rows - 0.5}) "
            f"({det.columns} x {det.rows} px); reduce the rate or the exposure"
        )


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
    """Counts of a single star at the boresight, static or smeared: the slew analysis' image.

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
    e = float(electrons)
    if not (math.isfinite(e) and e >= 0):
        raise InputError(f"electrons must be finite and >= 0, got {electrons!r}")
    if rate_rad_s is not None and streak_px is not None:
        raise InputError("give rate_rad_s or streak_px, not both")
    te = check_exposure(sensor.exposure_s if exposure_s is None else exposure_s)
    ox, oy = (float(v) for v in offset_px)
    cx, cy = sensor.principal_point_px
    x, y = cx + ox, cy + oy
    if streak_px is not None:
        dx, dy = (float(v) for v in streak_px)
        if not (math.isfinite(dx) and math.isfinite(dy)):
            raise InputError(f"streak_px must be finite, got {streak_px!r}")
        xs = np.array([x - dx / 2, x + dx / 2])
        ys = np.array([y - dy / 2, y + dy / 2])
        what = f"streak of ({dx:g}, {dy:g}) px"
    else:
        w = check_rate((0.0, 0.0, 0.0) if rate_rad_s is None else rate_rad_s)
        tracks = star_tracks(sensor, sensor.unproject([x], [y]), w, te)
        xs, ys = tracks.vertices[0][:, 0], tracks.vertices[0][:, 1]
        what = f"star at rate {w.tolist()} rad/s over {te:g} s"
    check_on_detector(sensor, np.append(xs, x), np.append(ys, y), what=what)
    pad = float(pad_sigma_for(e, _sigma(sensor))) if pad_sigma is None else float(pad_sigma)
    stamp, _ = polyline_expected(xs, ys, _sigma(sensor), e, pad_sigma=pad, method=method)
    if noise:
        return apply_noise(stamp, sensor, rng, exposure_s=te)
    return quantise(stamp, sensor)


# ---------------------------------------------------------------------------------------------


def _field_radius_rad(sensor) -> float:
    """Angle from the boresight to the farthest detector corner (distortion included)."""
    det = sensor.detector
    xc = np.array([-0.5, det.columns - 0.5, -0.5, det.columns - 0.5])
    yc = np.array([-0.5, -0.5, det.rows - 0.5, det.rows - 0.5])
    v = sensor.unproject(xc, yc)
    return float(np.max(np.arccos(np.clip(v[:, 2], -1.0, 1.0))))


def _band_and_colour(catalog, model: str, colour: str, band: str | None):
    """(band, magnitudes, colour name or None, colour indices or None) for the model."""
    if model == "blackbody":
        from starsense.photometry.colour import ColourModel

        cm = ColourModel(colour)
        use_band = band or cm.magnitude_band
        if colour not in catalog.colours:
            have = ", ".join(catalog.colours) or "none"
            raise InputError(
                f"catalogue {catalog.name!r} has no {colour!r} colour column for the blackbody "
                f"model; available colours: {have}"
            )
        ci = catalog.colours[colour]
        col = colour
    else:
        use_band, ci, col = band or "V", None, None
    if use_band not in catalog.mags:
        have = ", ".join(catalog.mags) or "none"
        raise InputError(
            f"catalogue {catalog.name!r} has no {use_band!r} magnitudes for the {model} model; "
            f"available bands: {have}"
        )
    return use_band, catalog.mags[use_band], col, ci


def render_frame(
    sensor,
    attitude: Rotation,
    catalog,
    *,
    rate_rad_s=(0.0, 0.0, 0.0),
    model: str = "reed",
    colour: str = "B-V",
    band: str | None = None,
    max_mag: float | None = None,
    rng=None,
    noise: bool = True,
    exposure_s: float | None = None,
    keep_expected: bool = True,
    method: str = "track",
) -> Frame:
    """Render one detector frame of a catalogue at an attitude and body rate.

    Parameters
    ----------
    sensor : Sensor
    attitude : scipy.spatial.transform.Rotation
        Mid-exposure attitude, ICRS -> camera (a single rotation).
    catalog : Catalog
        Stars (positions at the catalogue epoch).
    rate_rad_s : array_like, shape (3,)
        Constant body rate (wx, wy, wz) in the camera frame, rad/s.
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model (Dzamba & Enright eq. 8, eq. 6; black body per star).
    colour : str
        Colour system of the black-body model (e.g. "B-V"; its magnitude band is used).
    band : str, optional
        Override the catalogue band of the magnitudes (default V for reed / liebe, the colour
        system's band for blackbody).
    max_mag : float, optional
        Render only stars with magnitude <= max_mag.
    rng : None, int or numpy.random.Generator
        Noise source; an int (or None: a fresh seed is drawn) is recorded in the truth.
    noise : bool
        Add shot and read noise (else the quantised expected image).
    exposure_s : float, optional
        Exposure, s (default ``sensor.exposure_s``); scales the electrons and the streaks.
    keep_expected : bool
        Keep the float32 expected-electron image in the frame (default True).
    method : {"track", "closed-form"}
        Pixel quadrature of the smeared PSF (:mod:`starsense.render.smear`).

    Returns
    -------
    Frame
        Stars without a magnitude (or colour) in the needed column, or with non-finite
        electrons, are skipped; a selection with no stars gives a frame of noise only and an
        empty truth table.

    Raises
    ------
    InputError
        Bad rate (not 3 finite numbers), exposure (not finite and > 0), model, method,
        attitude, or a catalogue without the needed band / colour.
    """
    from starsense.photometry.sensitivity import Sensitivity

    w = check_rate(rate_rad_s)
    te = check_exposure(sensor.exposure_s if exposure_s is None else exposure_s)
    if model not in _MODELS:
        raise InputError(f"unknown sensitivity model {model!r}; choose {', '.join(_MODELS)}")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose {', '.join(METHODS)}")
    if not isinstance(attitude, Rotation) or not attitude.single:
        raise InputError(f"attitude must be a single scipy Rotation, got {attitude!r}")
    if max_mag is not None and (
        isinstance(max_mag, bool) or not isinstance(max_mag, numbers.Real) or math.isnan(max_mag)
    ):
        raise InputError(f"max_mag must be a number or None, got {max_mag!r}")
    gen, seed = as_generator(rng)
    if te != sensor.exposure_s:
        sensor = sensor.with_(exposure_s=te)
    det = sensor.detector
    sigma = _sigma(sensor)
    use_band, mags_all, col, ci_all = _band_and_colour(catalog, model, colour, band)

    # 1. candidate stars: the field, the sweep in half an exposure, and the PSF margin
    boresight = attitude.inv().apply([0.0, 0.0, 1.0])
    margin = 2.0 * (8.0 * sigma + 2.0) / sensor.focal_length_px
    radius = _field_radius_rad(sensor) + 0.5 * float(np.linalg.norm(w)) * te + margin
    idx = catalog.cone(boresight, min(radius, math.pi)) if len(catalog) else np.zeros(0, int)
    mags = mags_all[idx]
    keep = np.isfinite(mags)
    if max_mag is not None:
        keep &= mags <= max_mag
    ci = None
    if ci_all is not None:
        ci = ci_all[idx]
        keep &= np.isfinite(ci)
    idx, mags = idx[keep], mags[keep]
    ci = ci[keep] if ci is not None else np.full(idx.size, np.nan)

    # 2. electrons
    sens = Sensitivity.for_sensor(sensor, model, col or "B-V")
    electrons = np.asarray(
        sens.electrons(mags, ci if model == "blackbody" else None), dtype=float
    ).reshape(-1)
    ok = np.isfinite(electrons) & (electrons > 0)
    idx, mags, ci, electrons = idx[ok], mags[ok], ci[ok], electrons[ok]

    # 3. tracks and expected image
    vectors = attitude.apply(catalog.vectors[idx]) if idx.size else np.zeros((0, 3))
    tracks = star_tracks(sensor, vectors, w, te)
    pads = pad_sigma_for(electrons, sigma) * sigma
    expected = np.zeros((det.rows, det.columns), dtype=np.float32)
    rendered, on_det_e, on_det, nseg = [], [], [], []
    for i in range(idx.size):
        if not tracks.valid[i]:
            continue
        v = tracks.vertices[i]
        xs, ys = v[:, 0], v[:, 1]
        full = Box.around(xs.min(), xs.max(), ys.min(), ys.max(), pads[i])
        box = full.clip(det.rows, det.columns)
        if box is None:
            continue
        stamp, _ = polyline_expected(
            xs, ys, sigma, electrons[i], pad_sigma=pads[i] / sigma, box=box, method=method
        )
        expected[box.slices] += stamp
        rendered.append(i)
        on_det_e.append(float(stamp.sum()))
        inside = (xs >= -0.5) & (xs < det.columns - 0.5) & (ys >= -0.5) & (ys < det.rows - 0.5)
        on_det.append(bool(inside.all()))
        nseg.append(len(xs) - 1)
    r = np.asarray(rendered, dtype=np.intp)
    if r.size:
        stars = StarTruth(
            ids=catalog.ids[idx[r]].astype(np.int64),
            mag=mags[r].astype(float),
            colour_index=ci[r].astype(float) if model == "blackbody" else np.full(r.size, np.nan),
            electrons=electrons[r],
            electrons_on_detector=np.asarray(on_det_e),
            x_start=tracks.start[r, 0],
            y_start=tracks.start[r, 1],
            x_mid=tracks.mid[r, 0],
            y_mid=tracks.mid[r, 1],
            x_end=tracks.end[r, 0],
            y_end=tracks.end[r, 1],
            on_detector=np.asarray(on_det, dtype=bool),
            n_segments=np.asarray(nseg, dtype=np.int64),
        )
    else:
        stars = StarTruth.empty()

    # 4. detector
    if noise:
        image = apply_noise(expected, sensor, gen, exposure_s=te)
    else:
        image = quantise(expected, sensor)
    ra, dec, roll = radec_roll_from_attitude(attitude)
    truth = FrameTruth(
        sensor=sensor.name,
        catalog=catalog.name,
        attitude=attitude,
        ra_rad=float(ra),
        dec_rad=float(dec),
        roll_rad=float(roll),
        rate_rad_s=(float(w[0]), float(w[1]), float(w[2])),
        exposure_s=te,
        seed=seed,
        model=model,
        band=use_band,
        colour=col,
        max_mag=None if max_mag is None else float(max_mag),
        noise=bool(noise),
        method=method,
        stars=stars,
    )
    return Frame(image=image, expected_e=expected if keep_expected else None, truth=truth)
