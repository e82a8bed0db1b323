"""A camera class, seeded: faint 8-bit frames clipped at zero, with clutter.

The class of narrow science cameras read at 8 bits with a dark offset (the frames of
``shared/data/images/openstartracker`` are examples; nothing here is fitted to them): the
background sits at 0-2 counts with a read noise of 1.5-4 counts, so a third to two thirds of
the pixels are exactly 0; the brightest stars rise 10-100 counts, most a few counts above the
noise. On top, as real cameras of the class show:

- a **gradient** of the dark level across the frame (0-2 counts, a tilt and a bow);
- a **structured fixed pattern**: row banding (each row offset by a smoothed random walk,
  0.1-0.5 of the read noise) and a blotchy low-frequency pattern (a few random waves of
  30-150 px) over a third of the frame;
- **hot pixels** (20-300, 30-255 counts; a few as pairs, sharing charge with a neighbour);
- half the frames **colour**: three channels whose read noise is partly common (correlation
  0.6, as demosaicing leaves it), each clipped at zero and rounded on its own, stored as RGB
  (the solver reads their luminance: no longer on an integer lattice).

Every draw is a pure function of its seed: ``class_frame(seed, catalog)``.

Whether a frame carries the evidence a blind solver of the astrometry.net class needs is
decided from its truth, independently of any detector: ``evident`` when at least
:data:`EVIDENT_STARS` catalogue stars in the frame reach a matched-filter SNR of
:data:`EVIDENT_SNR` against the background's own noise (their expected counts over the
noise of a PSF-weighted sum, white noise). astrometry.net's default source extraction keeps
sources at ~8 sigma and its verification wants ~10 matched stars for a 1e-9-class odds ratio.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render.scene import render_frame
from starsense.sensor.load import sensor_from_dict

COLUMNS, ROWS, PITCH_M = 1024, 768, 5e-6
#: the class's evidence (module docstring): this many stars at this matched-filter SNR
EVIDENT_STARS = 10
EVIDENT_SNR = 8.0
#: luminance weights of an RGB frame (ITU-R BT.601, as starsense.solve.frames reads colour)
LUMA = np.array([0.299, 0.587, 0.114])
#: each channel's share of a star's counts (a camera's colour response to a white star)
CHANNEL_GAIN = np.array([0.9, 1.0, 0.75])
#: correlation of the three channels' read noise (what demosaicing leaves)
CHANNEL_RHO = 0.6


@dataclass(frozen=True)
class ClassFrame:
    """One frame of the class and its truth.

    Attributes
    ----------
    image : ndarray (rows, columns) uint8, or (rows, columns, 3) uint8 for colour
    attitude : Rotation
        The truth attitude (ICRS -> camera).
    fov_rad : float
        Horizontal field, rad.
    params : dict
        What was drawn (seeded).
    n_evident : int
        Catalogue stars in the frame at a matched-filter SNR >= :data:`EVIDENT_SNR`.
    """

    image: np.ndarray
    attitude: object
    fov_rad: float
    params: dict
    n_evident: int

    @property
    def evident(self) -> bool:
        """Whether the frame carries the evidence of the class (module docstring)."""
        return self.n_evident >= EVIDENT_STARS


def _sensor(fov_deg: float, psf_sigma_px: float, aperture_m: float):
    focal_m = COLUMNS * PITCH_M / (2 * math.tan(math.radians(fov_deg) / 2))
    return sensor_from_dict(
        {
            "name": "faint8",
            "exposure_s": 0.5,
            "optics": {"focal_length_m": focal_m, "aperture_m": aperture_m, "transmission": 1.0},
            "detector": {
                "columns": COLUMNS,
                "rows": ROWS,
                "pixel_pitch_m": PITCH_M,
                "bit_depth": 8,
                "gain_counts_per_e": 0.05,
                "read_noise_e": 1.0,  # the noise is drawn here, in counts (class_frame)
                "psf_sigma_px": psf_sigma_px,
                "qe_mean": 0.5,
                "bias_counts": 0.0,
                "full_well_e": 20000.0,
            },
        }
    )


def _smooth_walk(rng, n: int, scale: float) -> np.ndarray:
    """A random walk smoothed over ~8 samples, scaled to rms ``scale``."""
    w = np.cumsum(rng.standard_normal(n + 16))
    w = np.convolve(w - w.mean(), np.ones(8) / 8, mode="same")[8 : n + 8]
    w = w - w.mean()
    return scale * w / max(float(w.std()), 1e-12)


def _pattern(rng, noise: float) -> tuple[np.ndarray, dict]:
    """The fixed pattern, counts: row banding and blotches over a third of the frame."""
    band = rng.uniform(0.1, 0.5) * noise
    rows = _smooth_walk(rng, ROWS, band)
    y, x = np.mgrid[0:ROWS, 0:COLUMNS].astype(np.float32)
    blotch = np.zeros((ROWS, COLUMNS), np.float32)
    amp = rng.uniform(0.2, 0.6) * noise
    for _ in range(4):
        k = 2 * math.pi / rng.uniform(30.0, 150.0)
        t = rng.uniform(0.0, math.pi)
        blotch += np.cos(k * (x * math.cos(t) + y * math.sin(t)) + rng.uniform(0, 2 * math.pi))
    blotch *= amp / 2.0
    c0 = int(rng.integers(0, COLUMNS - COLUMNS // 3))
    cover = (x >= c0) & (x < c0 + COLUMNS // 3)
    pattern = rows[:, None] + np.where(cover, blotch, 0.0)
    return pattern.astype(np.float32), {"banding_counts": band, "blotch_counts": amp}


def _gradient(rng) -> tuple[np.ndarray, dict]:
    """The dark level's gradient, counts: a tilt across the columns and a bow."""
    tilt, bow = rng.uniform(0.0, 2.0), rng.uniform(-0.5, 0.5)
    y, x = np.mgrid[0:ROWS, 0:COLUMNS].astype(np.float32)
    u, v = x / COLUMNS, (y - ROWS / 2) / ROWS
    return (tilt * u + bow * (4 * v * v)).astype(np.float32), {"tilt_counts": tilt, "bow": bow}


def _hot(rng, image: np.ndarray) -> int:
    """Hot pixels in place (a fifth as pairs, the neighbour at 30-60 % of the pixel)."""
    n = int(rng.integers(20, 301))
    r, c = rng.integers(1, ROWS - 1, n), rng.integers(1, COLUMNS - 1, n)
    v = rng.integers(30, 256, n)
    image[r, c] = np.maximum(image[r, c], v[:, None] if image.ndim == 3 else v)
    pair = rng.random(n) < 0.2
    side = (v[pair] * rng.uniform(0.3, 0.6, int(pair.sum()))).astype(int)
    rr, cc = r[pair], c[pair] + 1
    image[rr, cc] = np.maximum(image[rr, cc], side[:, None] if image.ndim == 3 else side)
    return n


def class_frame(seed: int, catalog) -> ClassFrame:
    """Draw frame ``seed`` of the class (module docstring)."""
    rng = np.random.default_rng([49, seed])
    fov_deg = rng.uniform(4.5, 8.0)
    psf = rng.uniform(0.8, 1.5)
    sensor = _sensor(fov_deg, psf, aperture_m=rng.uniform(0.012, 0.025))
    ra, dec = rng.uniform(0.0, 360.0), math.degrees(math.asin(rng.uniform(-1.0, 1.0)))
    att = attitude_from_radec_roll(*np.radians([ra, dec, rng.uniform(0.0, 360.0)]))
    fr = render_frame(sensor, att, catalog, rng=int(rng.integers(2**31)), noise=False)
    gain = sensor.detector.gain_counts_per_e
    noise = rng.uniform(1.5, 4.0)  # read noise, counts
    offset = rng.uniform(-0.3, 1.5) * noise / 2  # dark level, counts: 35-60 % of pixels at 0
    colour = bool(rng.random() < 0.5)
    pattern, p_info = _pattern(rng, noise)
    gradient, g_info = _gradient(rng)
    dark = offset + gradient + pattern
    star_counts = rng.poisson(np.maximum(fr.expected_e, 0.0)) * gain
    if colour:
        common = rng.standard_normal((ROWS, COLUMNS)).astype(np.float32)
        chans = []
        for k in range(3):
            own = rng.standard_normal((ROWS, COLUMNS)).astype(np.float32)
            read = noise * (math.sqrt(CHANNEL_RHO) * common + math.sqrt(1 - CHANNEL_RHO) * own)
            chans.append(star_counts * CHANNEL_GAIN[k] + dark + read)
        image = np.clip(np.rint(np.stack(chans, axis=-1)), 0, 255).astype(np.uint8)
    else:
        read = noise * rng.standard_normal((ROWS, COLUMNS)).astype(np.float32)
        image = np.clip(np.rint(star_counts + dark + read), 0, 255).astype(np.uint8)
    n_hot = _hot(rng, image)
    # the class's evidence, from the truth: each star's counts over the matched filter's noise
    stars = fr.truth.stars
    on = stars.on_detector
    counts = stars.electrons[on] * gain * (float(LUMA @ CHANNEL_GAIN) if colour else 1.0)
    pix = _pixel_noise(noise, offset, colour)
    snr = counts / (pix * math.sqrt(4 * math.pi) * psf)
    params = {
        "seed": seed,
        "fov_deg": fov_deg,
        "psf_sigma_px": psf,
        "read_noise_counts": noise,
        "offset_counts": offset,
        "colour": colour,
        "hot_pixels": n_hot,
        **p_info,
        **g_info,
    }
    return ClassFrame(image, att, math.radians(fov_deg), params, int((snr >= EVIDENT_SNR).sum()))


def _pixel_noise(noise: float, offset: float, colour: bool) -> float:
    """Std of a background pixel after clipping at zero (and the luminance of colour), counts.

    From a large seeded draw of the same process, independent of the frame.
    """
    rng = np.random.default_rng(0)
    if not colour:
        v = np.clip(np.rint(offset + noise * rng.standard_normal(200_000)), 0, None)
        return float(v.std())
    common = rng.standard_normal(200_000)
    ch = [
        np.clip(
            np.rint(
                offset
                + noise
                * (
                    math.sqrt(CHANNEL_RHO) * common
                    + math.sqrt(1 - CHANNEL_RHO) * rng.standard_normal(200_000)
                )
            ),
            0,
            None,
        )
        for _ in range(3)
    ]
    return float((np.stack(ch, axis=-1) @ LUMA).std())


def luminance(image: np.ndarray) -> np.ndarray:
    """The frame as starsense reads it from a file: colour to luminance, grey as it is."""
    return image.astype(float) @ LUMA if image.ndim == 3 else image
