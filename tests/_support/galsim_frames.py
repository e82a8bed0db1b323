"""Frames drawn by GalSim: an independent renderer to check our renderer, solver and datasheet.

:func:`galsim_frame` draws a detector frame of a catalogue at an attitude and body rate with
`GalSim <https://galsim-developers.github.io/GalSim/>`_: each star is a GalSim profile
(Gaussian, Airy, Moffat or an aberrated optical PSF) of the sensor's PSF width, convolved with
the pixel and, for a moving camera, along its track; the detector response (shot noise, dark
charge, read noise, gain, bias, full well, ADC) is written out here with NumPy. Nothing of
``starsense.render`` is used: starsense supplies the geometry (catalogue cone, the attitude and
``Sensor.project``) and the photometry (``Sensitivity``: magnitude -> electrons) only, so the
pixels come from a renderer nobody here wrote.

Conventions (those of :func:`starsense.render.scene.render_frame`): ``attitude`` is the
ICRS -> camera rotation at **mid-exposure**; with the body rate ``w`` (camera frame, rad/s)
a star's camera direction at time ``t`` in ``[0, t_e]`` is ``R(-w (t - t_e/2)) A v``; its pixel
position is ``sensor.project`` of that (pixel (c, r) covers ``[c - 1/2, c + 1/2) x
[r - 1/2, r + 1/2)``). The truth's ``x_mid, y_mid`` is ``sensor.project(A v)``.

The PSFs and their stamps: :mod:`galsim_psf`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from galsim_psf import (  # noqa: F401  (re-exported)
    FWHM_PER_SIGMA,
    PSF_DEFAULTS,
    PSF_KINDS,
    _galsim,
    _options,
    psf_profile,
    stamp_radius_px,
)
from scipy.spatial.transform import Rotation

from starsense.catalog import load_catalog
from starsense.photometry.sensitivity import Sensitivity

__all__ = [
    "FWHM_PER_SIGMA",
    "PSF_KINDS",
    "GalsimFrame",
    "GalsimStars",
    "GalsimTruth",
    "galsim_frame",
    "psf_profile",
    "read_out",
    "stamp_radius_px",
]


#: largest step between the PSFs summed along a curved track, px
MAX_STEP_PX = 0.2
#: a track within this of straight, uniform motion is drawn as the PSF convolved with a box, px
STRAIGHT_TOL_PX = 0.01
#: stars of fewer expected electrons are photon-shot in noisy frames (galsim_frame)
SHOOT_BELOW_E = 3000.0


@dataclass(frozen=True)
class GalsimStars:
    """The stars drawn (those whose stamp reaches the detector), one entry each.

    Attributes
    ----------
    ids : ndarray of int64
        Catalogue identifiers.
    mag : ndarray
        Magnitudes in the band of the sensitivity model (V).
    electrons : ndarray
        Expected photo-electrons of the whole star over the exposure.
    electrons_drawn : ndarray
        Expected electrons its stamp put on the detector (clipped stamp, wings left out).
    x_mid, y_mid, x_start, y_start, x_end, y_end : ndarray
        Pixel positions at mid-exposure, start and end.
    inside : ndarray of bool
        Its whole stamp lies on the detector.
    """

    ids: np.ndarray
    mag: np.ndarray
    electrons: np.ndarray
    electrons_drawn: np.ndarray
    x_mid: np.ndarray
    y_mid: np.ndarray
    x_start: np.ndarray
    y_start: np.ndarray
    x_end: np.ndarray
    y_end: np.ndarray
    inside: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.size)


@dataclass(frozen=True)
class GalsimTruth:
    """What a GalSim frame shows: attitude at mid-exposure, rate, PSF and the stars."""

    attitude: Rotation
    rate_rad_s: tuple[float, float, float]
    exposure_s: float
    psf: str
    psf_options: dict
    fwhm_px: float
    seed: int | None
    stars: GalsimStars


@dataclass(frozen=True)
class GalsimFrame:
    """A frame: counts (the detector's dtype), the expected electrons and the truth."""

    image: np.ndarray
    truth: GalsimTruth
    expected_e: np.ndarray | None = field(default=None, repr=False)


def read_out(expected_e, detector, *, exposure_s: float, rng, photons=None) -> np.ndarray:
    """Return the counts of a detector from its expected electrons (written here, NumPy only).

    Charge ``Poisson(S + D t_e)`` clipped at the full well, plus read noise ``N(0, r^2)``
    electrons; ``counts = gain x charge + bias`` rounded to the nearest integer and clipped
    to ``[0, 2^bits - 1]``; ``uint16`` for up to 16 bits, else ``uint32``. ``rng=None``: no
    noise (the expected electrons, clipped, converted and rounded). ``photons``: charge
    already drawn (photons shot by GalSim, Poisson by construction), added before the clip.
    """
    det = detector
    # an FFT-drawn profile rings at ~1e-8 of its peak below zero far out: no charge there
    e = np.maximum(np.asarray(expected_e, dtype=np.float64), 0.0)
    charge = e + det.dark_current_e_s * exposure_s
    if rng is not None:
        charge = rng.poisson(charge).astype(np.float64)
    if photons is not None:
        charge += photons
    np.minimum(charge, det.full_well_e, out=charge)
    if rng is not None and det.read_noise_e > 0:
        charge += rng.normal(0.0, det.read_noise_e, charge.shape)
    counts = np.rint(charge * det.gain_counts_per_e + det.bias_counts)
    np.clip(counts, 0, 2**det.bit_depth - 1, out=counts)
    return counts.astype(np.uint16 if det.bit_depth <= 16 else np.uint32)


def _check_sensor(sensor) -> None:
    det, opt = sensor.detector, sensor.optics
    extra = {
        "detector.prnu_fraction": det.prnu_fraction,
        "detector.dsnu_e": det.dsnu_e,
        "detector.hot_pixel_fraction": det.hot_pixel_fraction,
        "optics.distortion_residual_px": opt.distortion_residual_px,
        "optics.psf_sigma_corner_px": opt.psf_sigma_corner_px,
    }
    drawn = {k: v for k, v in extra.items() if v}
    if drawn:
        raise ValueError(f"galsim_frame does not draw {drawn}: set them to 0")


def _field_radius_rad(sensor) -> float:
    det = sensor.detector
    xc = np.array([-0.5, det.columns - 0.5, -0.5, det.columns - 0.5])
    yc = np.array([-0.5, -0.5, det.rows - 0.5, det.rows - 0.5])
    return float(np.max(np.arccos(np.clip(sensor.unproject(xc, yc)[:, 2], -1.0, 1.0))))


def _positions(sensor, v_mid, w, te, fractions) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions (N, T) at times ``fractions * t_e`` of mid-exposure directions (N, 3)."""
    tau = (np.asarray(fractions, dtype=float) - 0.5) * te
    rot = Rotation.from_rotvec(-tau[:, None] * w[None, :]).as_matrix()  # (T, 3, 3)
    return sensor.project(np.einsum("tij,nj->nti", rot, v_mid))


def _stars_in_view(sensor, attitude, catalog, w, te, margin_px, model, max_mag):
    """Catalogue stars that can reach the detector: indices, magnitudes, electrons, vectors."""
    mags_all = np.asarray(catalog.mags["V"], dtype=float)
    boresight = attitude.inv().apply([0.0, 0.0, 1.0])
    radius = (
        _field_radius_rad(sensor)
        + 0.5 * float(np.linalg.norm(w)) * te
        + 2.0 * margin_px / sensor.focal_length_px
    )
    idx = np.asarray(catalog.cone(boresight, min(radius, math.pi)), dtype=np.int64)
    mags = mags_all[idx]
    keep = np.isfinite(mags) & (mags <= (np.inf if max_mag is None else max_mag))
    idx, mags = idx[keep], mags[keep]
    e = np.asarray(Sensitivity.for_sensor(sensor, model).electrons(mags), dtype=float).ravel()
    ok = np.isfinite(e) & (e > 0)
    idx, mags, e = idx[ok], mags[ok], e[ok]
    v = attitude.apply(catalog.vectors[idx]) if idx.size else np.zeros((0, 3))
    front = v[:, 2] > 0
    return idx[front], mags[front], e[front], v[front]


def _track_profile(psf, x, y, electrons):
    """The profile of one star over its track (positions (T,) at equal times), and its centre.

    Static: the PSF at the point. Straight uniform motion (within :data:`STRAIGHT_TOL_PX`):
    the PSF convolved with a box along the chord. Otherwise: the PSF summed at the midpoints
    of equal time steps no longer than :data:`MAX_STEP_PX`.
    """
    galsim = _galsim()
    xs, ys, xe, ye = x[0], y[0], x[-1], y[-1]
    chord = math.hypot(xe - xs, ye - ys)
    if chord < 1e-6:
        return psf.withFlux(electrons), (float(x[x.size // 2]), float(y[y.size // 2]))
    t = np.linspace(0.0, 1.0, x.size)
    dev = np.hypot(x - (xs + t * (xe - xs)), y - (ys + t * (ye - ys))).max()
    centre = (0.5 * (xs + xe), 0.5 * (ys + ye))
    if dev <= STRAIGHT_TOL_PX:
        box = galsim.Box(chord, 1e-3, gsparams=psf.gsparams)
        box = box.rotate(math.atan2(ye - ys, xe - xs) * galsim.radians)
        prof = galsim.Convolve(psf, box, real_space=False, gsparams=psf.gsparams)
        return prof.withFlux(electrons), centre
    return None, centre  # curved: summed by the caller at finer steps


def _curved_profile(psf, sensor, v, w, te, path_px, electrons):
    galsim = _galsim()
    k = max(2, math.ceil(path_px / MAX_STEP_PX))
    x, y = _positions(sensor, v[None, :], w, te, (np.arange(k) + 0.5) / k)
    x, y = x[0], y[0]
    cx, cy = float(x.mean()), float(y.mean())
    parts = [psf.shift(float(a - cx), float(b - cy)) for a, b in zip(x, y, strict=True)]
    return galsim.Add(parts).withFlux(electrons), (cx, cy)


def _draw(image, prof, centre, bounds, shoot=None):
    """Draw ``prof`` centred at ``centre`` (px) on the pixels of ``bounds``; its sum, e-.

    ``shoot``: a ``galsim.BaseDeviate`` to shoot photons with (else the expected electrons).
    """
    galsim = _galsim()
    b = bounds & image.bounds
    if not b.isDefined():
        return float("nan")  # no pixel of the detector
    stamp = galsim.ImageD(b, scale=1.0)
    tc = stamp.true_center
    offset = (centre[0] - tc.x, centre[1] - tc.y)
    if shoot is None:
        prof.drawImage(image=stamp, offset=offset, method="auto")
    else:  # photons drawn from the profile land in pixels: the pixel response, shot noise
        prof.drawImage(image=stamp, offset=offset, method="phot", rng=shoot)
    image[b] += stamp
    return float(stamp.array.sum())


def _draw_stars(images, psf, radius, sensor, v, e, w, te, shoot):
    """Draw every star; return (x, y) at start / mid / end (N, 6), drawn e- and inside flags.

    ``images``: (expected, photons); ``shoot``: (deviate, electrons below which a star's
    photons are shot onto ``photons``) or None.
    """
    image = images[0]
    galsim = _galsim()
    n = len(e)
    moving = float(np.linalg.norm(w)) * te > 0
    samples = 1
    if moving:
        # enough samples to see a track's length and straightness (step <= 1/4 of it, >= 9)
        reach = float(np.linalg.norm(w)) * te * sensor.focal_length_px
        samples = max(9, min(257, 2 * math.ceil(reach) + 1))
    x, y = _positions(sensor, v, w, te, np.linspace(0.0, 1.0, samples) if moving else [0.5])
    ends = np.stack([x[:, 0], y[:, 0], x[:, x.shape[1] // 2], y[:, x.shape[1] // 2],
                     x[:, -1], y[:, -1]], axis=1)  # fmt: skip
    drawn, inside = np.zeros(n), np.zeros(n, bool)
    for i in range(n):
        xi, yi = x[i], y[i]
        if not (np.isfinite(xi).all() and np.isfinite(yi).all()):
            continue
        prof, centre = _track_profile(psf, xi, yi, e[i])
        if prof is None:
            path = float(np.hypot(np.diff(xi), np.diff(yi)).sum())
            prof, centre = _curved_profile(psf, sensor, v[i], w, te, path, e[i])
        lo_x, hi_x = math.floor(xi.min() + 0.5) - radius, math.floor(xi.max() + 0.5) + radius
        lo_y, hi_y = math.floor(yi.min() + 0.5) - radius, math.floor(yi.max() + 0.5) + radius
        bounds = galsim.BoundsI(lo_x, hi_x, lo_y, hi_y)
        inside[i] = image.bounds.includes(bounds)
        if shoot is not None and e[i] < shoot[1]:
            drawn[i] = _draw(images[1], prof, centre, bounds, shoot[0])
        else:
            drawn[i] = _draw(image, prof, centre, bounds)
    return ends, drawn, inside


_ENDS = ("x_start", "y_start", "x_mid", "y_mid", "x_end", "y_end")


def galsim_frame(
    sensor,
    attitude: Rotation,
    *,
    psf: str = "gaussian",
    rate_rad_s=(0.0, 0.0, 0.0),
    catalog=None,
    seed=None,
    noise: bool = True,
    model: str = "reed",
    max_mag: float | None = None,
    psf_options: dict | None = None,
    exposure_s: float | None = None,
    keep_expected: bool = False,
    shoot_below_e: float = SHOOT_BELOW_E,
) -> GalsimFrame:
    """Draw one frame with GalSim (see the module docstring).

    Parameters
    ----------
    sensor : Sensor
        Geometry (``project``), photometry and detector response.
    attitude : scipy.spatial.transform.Rotation
        ICRS -> camera at mid-exposure.
    psf : {"gaussian", "airy", "moffat", "optical"}
        The PSF kind, of the FWHM of the sensor's Gaussian ``psf_sigma_px``.
    rate_rad_s : array_like, shape (3,)
        Body rate in the camera frame, rad/s.
    catalog : Catalog or str, optional
        The stars (default: the bundled Hipparcos), V magnitudes.
    seed : None, int or numpy.random.Generator
        Noise source (an int is recorded in the truth).
    noise : bool
        Draw shot and read noise (else the expected electrons, converted and rounded).
    model : {"reed", "liebe"}
        Sensitivity model (magnitude -> electrons) of ``starsense.photometry``.
    max_mag : float, optional
        Draw only stars at most this magnitude.
    psf_options : dict, optional
        The PSF's shape parameters (:data:`PSF_DEFAULTS`).
    exposure_s : float, optional
        Exposure (default ``sensor.exposure_s``).
    keep_expected : bool
        Keep the float64 expected-electron image (every star drawn into it).
    shoot_below_e : float
        With noise (and no ``keep_expected``), stars of fewer expected electrons are drawn by
        shooting their photons (GalSim's ``method="phot"``: Poisson in number, each landing
        in the pixel it falls in), 10-20 times faster than their FFT for the faint majority
        of a frame's stars; the same statistics. 0: every star by FFT.

    Returns
    -------
    GalsimFrame
    """
    galsim = _galsim()
    _check_sensor(sensor)
    te = float(sensor.exposure_s if exposure_s is None else exposure_s)
    if te != sensor.exposure_s:
        sensor = sensor.with_(exposure_s=te)
    w = np.asarray(rate_rad_s, dtype=float).reshape(3)
    catalog = load_catalog("hipparcos" if catalog is None else catalog)
    det = sensor.detector
    fwhm = FWHM_PER_SIGMA * float(det.psf_sigma_px)
    opts = _options(psf, psf_options)
    profile = psf_profile(psf, fwhm, **opts)
    radius = stamp_radius_px(psf, fwhm, **opts)
    idx, mags, e, v = _stars_in_view(sensor, attitude, catalog, w, te, radius + 2, model, max_mag)
    image = galsim.ImageD(det.columns, det.rows, xmin=0, ymin=0, scale=1.0)
    if isinstance(seed, np.random.Generator):
        rng, recorded = seed, None
    else:
        recorded = int(np.random.SeedSequence().entropy % 2**63) if seed is None else int(seed)
        rng = np.random.default_rng(recorded)
    shoot = photons = None
    if noise and not keep_expected and shoot_below_e > 0:
        photons = galsim.ImageD(det.columns, det.rows, xmin=0, ymin=0, scale=1.0)
        shoot = (galsim.BaseDeviate(int(rng.integers(1, 2**31))), float(shoot_below_e))
    ends, drawn, inside = _draw_stars((image, photons), profile, radius, sensor, v, e, w, te,
                                      shoot)  # fmt: skip
    hit = np.isfinite(drawn)
    stars = GalsimStars(
        ids=np.asarray(catalog.ids, dtype=np.int64)[idx][hit],
        mag=mags[hit],
        electrons=e[hit],
        electrons_drawn=drawn[hit],
        **{k: ends[hit, j] for j, k in enumerate(_ENDS)},
        inside=inside[hit],
    )
    expected = image.array
    counts = read_out(expected, det, exposure_s=te, rng=rng if noise else None,
                      photons=None if photons is None else photons.array)  # fmt: skip
    truth = GalsimTruth(
        attitude=attitude,
        rate_rad_s=(float(w[0]), float(w[1]), float(w[2])),
        exposure_s=te,
        psf=psf,
        psf_options=opts,
        fwhm_px=fwhm,
        seed=recorded,
        stars=stars,
    )
    return GalsimFrame(image=counts, truth=truth, expected_e=expected if keep_expected else None)
