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

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._validate import as_generator
from starsense.catalog import DEFAULT_CATALOG, Catalog, load_catalog
from starsense.catalog.apparent import apparent_places
from starsense.errors import InputError
from starsense.geometry.attitude import radec_roll_from_attitude
from starsense.photometry.colour import ColourModel
from starsense.photometry.sensitivity import Sensitivity
from starsense.render.frame import Frame, FrameTruth, StarTruth
from starsense.render.model_stamps import model_expected_image
from starsense.render.noise import apply_noise, quantise
from starsense.render.readout import fast_read_out
from starsense.render.smear import METHODS
from starsense.render.stamps import expected_image
from starsense.render.tracks import Tracks, check_rate, star_tracks
from starsense.sensor import Sensor, load_sensor

__all__ = [
    "MAX_RENDER_PIXELS",
    "check_frame_size",
    "check_on_detector",
    "render_frame",
]

#: largest detector a frame is rendered for, pixels (8192 x 8192): a frame holds ~30 bytes a
#: pixel while it is rendered (expected electrons, noise, counts), ~2 GB at this size
MAX_RENDER_PIXELS = 1 << 26


def as_render_sensor(sensor) -> Sensor:
    """Return ``sensor`` as a Sensor: itself, or a preset name or TOML path loaded.

    Raises
    ------
    InputError
        Anything else, named with its type (not an AttributeError from deep inside).
    """
    return sensor if isinstance(sensor, Sensor) else load_sensor(sensor)


def check_frame_size(sensor) -> None:
    """Refuse, before any work, a detector too large to render a frame of.

    Parameters
    ----------
    sensor : Sensor
        The sensor whose full detector frame would be rendered.

    Raises
    ------
    InputError
        ``columns x rows`` above :data:`MAX_RENDER_PIXELS`, naming the size and the limit.
    """
    det = sensor.detector
    n = det.columns * det.rows
    if n > MAX_RENDER_PIXELS:
        raise InputError(
            f"detector.columns x detector.rows = {det.columns} x {det.rows} = {n:,} pixels: "
            f"more than the {MAX_RENDER_PIXELS:,} (8192 x 8192) a rendered frame may have "
            f"(~30 bytes a pixel while rendering: {n * 30 / 2**30:.0f} GiB)"
        )


_MODELS = ("reed", "liebe", "blackbody")


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


def _star_truth(catalog, stars, tracks: Tracks, rendered, model: str) -> StarTruth:
    """Build the truth table of the stars that touch the detector (step 3's ``rendered``)."""
    idx, mags, ci, electrons = stars
    r, on_det_e, on_det, nseg = rendered
    if not r.size:
        return StarTruth.empty()
    return StarTruth(
        ids=catalog.ids[idx[r]].astype(np.int64),
        mag=mags[r].astype(float),
        colour_index=ci[r].astype(float) if model == "blackbody" else np.full(r.size, np.nan),
        electrons=electrons[r],
        electrons_on_detector=on_det_e,
        x_start=tracks.start[r, 0],
        y_start=tracks.start[r, 1],
        x_mid=tracks.mid[r, 0],
        y_mid=tracks.mid[r, 1],
        x_end=tracks.end[r, 0],
        y_end=tracks.end[r, 1],
        on_detector=on_det,
        n_segments=nseg,
    )


def _check_render_options(attitude, model: str, method: str, max_mag) -> None:
    """Raise :class:`InputError` for an unknown model or method, a bad attitude or max_mag."""
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


def _residual(sensor, tracks: Tracks, gen) -> Tracks:
    """Displace each star by the distortion calibration's residual (the truth keeps the ideal).

    ``optics.distortion_residual_px`` rms per axis, independent per star, the whole track moved
    together; no draw when it is 0.
    """
    r = sensor.optics.distortion_residual_px
    if r <= 0.0 or not len(tracks):
        return tracks
    shift = r * gen.standard_normal((len(tracks), 2))
    return dataclasses.replace(
        tracks, vertices=tuple(v + d for v, d in zip(tracks.vertices, shift, strict=True))
    )


def _field_stars(sensor, attitude, catalog, w, te, mags_all, ci_all, max_mag):
    """Step 1: catalogue stars that can reach the detector, with a magnitude (and colour).

    The cone is the field, the sweep in half an exposure, and the PSF margin. Returns the
    catalogue indices, magnitudes and colour indices (NaN without a colour model).
    """
    sigma = max(_sigma(sensor), sensor.optics.psf_sigma_corner_px)
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
    return idx, mags, ci


def _with_electrons(stars, sensor, model: str, col: str | None):
    """Step 2: the stars' electrons; those with none (or not finite) are dropped."""
    idx, mags, ci = stars
    sens = Sensitivity.for_sensor(sensor, model, col or "B-V")
    electrons = np.asarray(
        sens.electrons(mags, ci if model == "blackbody" else None), dtype=float
    ).reshape(-1)
    ok = np.isfinite(electrons) & (electrons > 0)
    return idx[ok], mags[ok], ci[ok], electrons[ok]


def render_frame(
    sensor,
    rotation: Rotation,
    catalog: Catalog | str | None = None,
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
    obs_time=None,
    observer_velocity_m_s=None,
    fast_noise: bool = False,
) -> Frame:
    """Render one detector frame of a catalogue at an attitude and body rate.

    Parameters
    ----------
    sensor : Sensor, str or Path
        The star tracker (optics, detector, exposure), e.g. from
        :func:`starsense.sensor.load_sensor`, or a preset name or sensor TOML file.
    rotation : scipy.spatial.transform.Rotation
        Mid-exposure attitude, ICRS -> camera (a single rotation; see
        :func:`starsense.geometry.attitude.attitude_from_radec_roll`).
    catalog : Catalog or str, optional
        Stars (positions at the catalogue epoch): a :class:`~starsense.catalog.Catalog`, or a
        catalogue spec read by :func:`starsense.catalog.load_catalog` (default: the bundled
        Hipparcos catalogue, ``"hipparcos"``).
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
    obs_time : str or astropy.time.Time, optional
        When the frame is taken (ISO 8601 UTC): the stars are then rendered at their apparent
        places (proper motion, parallax, aberration; :mod:`starsense.catalog.apparent`), as a
        real camera sees them.
    observer_velocity_m_s : array_like, shape (3,), optional
        The observer's velocity relative to the geocentre, ICRS axes, m/s (with ``obs_time``).
    fast_noise : bool
        Read the frame out with :func:`~starsense.render.readout.fast_read_out` where it
        applies: the statistics of the default read-out (within the bounds it states) in about
        half the time, other random draws (Monte Carlo runs of thousands of frames).

    Returns
    -------
    Frame
        The image (``image``), the expected electrons (``expected_e``) and the truth
        (``truth``: attitude, rate, seed and the rendered stars).
        Stars without a magnitude (or colour) in the needed column, or with non-finite
        electrons, are skipped; a selection with no stars gives a frame of noise only and an
        empty truth table.

    Raises
    ------
    InputError
        Bad rate (not 3 finite numbers), exposure (not finite and > 0), model, method,
        attitude, or a catalogue without the needed band / colour.
    """
    sensor = as_render_sensor(sensor)
    check_frame_size(sensor)
    catalog = load_catalog(DEFAULT_CATALOG if catalog is None else catalog)
    w = check_rate(rate_rad_s)
    te = sensor.exposure_or(exposure_s)
    _check_render_options(rotation, model, method, max_mag)
    gen, seed = as_generator(rng)
    if te != sensor.exposure_s:
        sensor = sensor.with_(exposure_s=te)
    use_band, mags_all, col, ci_all = _band_and_colour(catalog, model, colour, band)
    # 1. candidate stars, 2. their electrons
    stars = _field_stars(sensor, rotation, catalog, w, te, mags_all, ci_all, max_mag)
    stars = _with_electrons(stars, sensor, model, col)
    idx, electrons = stars[0], stars[3]
    # 3. tracks and the expected image
    sky, apparent = catalog.vectors[idx], None
    if obs_time is not None and idx.size:
        places = apparent_places(
            catalog, idx, obs_time, observer_velocity_m_s=observer_velocity_m_s
        )
        sky, apparent = places.vectors, places.to_dict()
    elif observer_velocity_m_s is not None:
        raise InputError("observer_velocity_m_s needs obs_time")
    vectors = rotation.apply(sky) if idx.size else np.zeros((0, 3))
    tracks = star_tracks(sensor, vectors, rate_rad_s=w, exposure_s=te)
    mid = tracks.mid if len(tracks) else np.zeros((0, 2))
    sigmas = sensor.psf_sigma_at(mid[:, 0], mid[:, 1])  # the field-dependent PSF, per star
    sigmas = np.where(np.isfinite(sigmas), sigmas, _sigma(sensor))
    moved = _residual(sensor, tracks, gen)
    if sensor.psf.is_gaussian:
        expected, rendered = expected_image(sensor, moved, electrons, method=method, sigmas=sigmas)
    else:  # the forward model's profile (Moffat, Airy, empirical)
        expected, rendered = model_expected_image(sensor, moved, electrons, sigmas=sigmas)
    truth_stars = _star_truth(catalog, stars, tracks, rendered, model)

    # 4. detector
    image = None
    if noise and fast_noise:
        image = fast_read_out(expected, sensor, rng=gen, exposure_s=te)  # None: not applicable
    if image is None:
        image = (
            apply_noise(expected, sensor, rng=gen, exposure_s=te)
            if noise
            else quantise(expected, sensor)
        )
    ra, dec, roll = radec_roll_from_attitude(rotation)
    truth = FrameTruth(
        sensor=sensor.name,
        catalog=catalog.name,
        attitude=rotation,
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
        stars=truth_stars,
        apparent=apparent,
    )
    return Frame(image=image, expected_e=expected if keep_expected else None, truth=truth)
