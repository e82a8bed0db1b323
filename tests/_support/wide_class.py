"""A camera class, seeded: wide undersampled frames of a space imager (stars in one or two pixels).

Frames summed on board to 0.2-0.35 deg per pixel over a 40-68 deg field (130-300 px across):
the optics' PSF (sigma 0.3-0.5 px) puts most of a star in one pixel, the brightest neighbour
holding 5-25 % of it, so a star looks like what a single-frame detector calls a hot pixel.
Hundreds of catalogue stars are in view. On top, as such imagers show:

- a **stray-light gradient**: a glow falling off exponentially from one side of the frame,
  10-60 read-noise sigmas at that side, over a scale of a third to one frame;
- a **bleed column** from a saturated object (a planet's blob at full scale whose charge runs
  up and down its column, 10-40 % of the rows);
- **hot pixels** (5-30, 20-80 % of full scale), at places fixed for a camera (``camera`` seed):
  every frame of one camera holds the same ones, as a real detector's defects;
- read noise 2-6 counts on a 12-bit scale, Poisson photons.

Every draw is a pure function of its seeds: ``wide_frame(seed, catalog, camera=...)``.

The class's evidence is decided from the truth, independently of any detector, as for the
faint 8-bit class (tests/_support/camera_class.py): ``evident`` when at least
:data:`EVIDENT_STARS` catalogue stars in the frame reach a matched-filter SNR of
:data:`EVIDENT_SNR` (their expected counts over the noise of a PSF-weighted sum of white
noise of the frame's background, floor 1 pixel: an undersampled PSF's sum is one pixel's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.render.scene import render_frame
from starsense.sensor.load import sensor_from_dict

#: the class's evidence (module docstring): this many stars at this matched-filter SNR
EVIDENT_STARS = 10
EVIDENT_SNR = 8.0
PITCH_M = 20e-6
FULL_SCALE = 4095


@dataclass(frozen=True)
class WideFrame:
    """One wide undersampled frame and its truth.

    Attributes
    ----------
    image : ndarray (rows, columns) uint16
    attitude : Rotation
        The truth attitude (ICRS -> camera).
    fov_rad : float
        Horizontal field, rad.
    params : dict
        What was drawn (seeded).
    n_evident : int
        Catalogue stars in the frame at a matched-filter SNR >= :data:`EVIDENT_SNR`.
    star_xy : ndarray (M, 2)
        The truth places of the catalogue stars on the frame, brightest first, px.
    hot_xy : ndarray (H, 2)
        The hot pixels' places (column, row).
    """

    image: np.ndarray
    attitude: object
    fov_rad: float
    params: dict
    n_evident: int
    star_xy: np.ndarray
    hot_xy: np.ndarray

    @property
    def evident(self) -> bool:
        """Whether the frame carries the evidence of the class (module docstring)."""
        return self.n_evident >= EVIDENT_STARS


def _camera(camera: int) -> dict:
    """The camera: size, scale, PSF, optics, and its hot pixels' places and levels."""
    rng = np.random.default_rng([5049, camera])
    scale_deg = rng.uniform(0.2, 0.35)
    fov_deg = rng.uniform(40.0, 68.0)
    cols = round(fov_deg / scale_deg)
    rows = round(0.75 * cols)
    n_hot = int(rng.integers(5, 31))
    hot = np.column_stack([rng.integers(1, cols - 1, n_hot), rng.integers(1, rows - 1, n_hot)])
    return {
        "columns": cols,
        "rows": rows,
        "fov_deg": cols * scale_deg,
        "psf_sigma_px": rng.uniform(0.3, 0.5),
        "aperture_m": rng.uniform(0.004, 0.008),
        "read_noise_counts": rng.uniform(2.0, 6.0),
        "hot_xy": hot,
        "hot_counts": rng.uniform(0.2, 0.8, n_hot) * FULL_SCALE,
    }


def _sensor(cam: dict):
    fov = math.radians(cam["fov_deg"])
    focal_m = cam["columns"] * PITCH_M / (2 * math.tan(fov / 2))
    return sensor_from_dict(
        {
            "name": "wide_undersampled",
            "exposure_s": 1.0,
            "optics": {
                "focal_length_m": focal_m,
                # no faster than f/0.55 (a physical lens: f/0.5 is the limit in air)
                "aperture_m": min(cam["aperture_m"], focal_m / 0.55),
                "transmission": 1.0,
            },
            "detector": {
                "columns": cam["columns"],
                "rows": cam["rows"],
                "pixel_pitch_m": PITCH_M,
                "bit_depth": 12,
                "gain_counts_per_e": 0.02,
                "read_noise_e": 1.0,  # the noise is drawn here, in counts (wide_frame)
                "psf_sigma_px": cam["psf_sigma_px"],
                "qe_mean": 0.5,
                "bias_counts": 0.0,
                "full_well_e": 1e6,
            },
        }
    )


def _stray(rng, rows: int, cols: int, noise: float) -> tuple[np.ndarray, dict]:
    """The stray light: an exponential glow from one side, counts."""
    level = rng.uniform(10.0, 60.0) * noise
    length = rng.uniform(1 / 3, 1.0) * max(rows, cols)
    t = rng.uniform(0.0, 2 * math.pi)
    y, x = np.mgrid[0:rows, 0:cols].astype(float)
    # distance from the lit side along the direction t
    d = (x - cols / 2) * math.cos(t) + (y - rows / 2) * math.sin(t)
    d = d.max() - d
    return level * np.exp(-d / length), {"stray_counts": level, "stray_length_px": length}


def _bleed(rng, image: np.ndarray) -> dict:
    """A saturated object (a blob at full scale) whose charge bleeds along its column."""
    rows, cols = image.shape
    c, r = int(rng.integers(5, cols - 5)), int(rng.integers(5, rows - 5))
    half = int(rng.uniform(0.05, 0.2) * rows)
    image[max(r - half, 0) : r + half + 1, c] = FULL_SCALE
    y, x = np.mgrid[0:rows, 0:cols]
    blob = np.hypot(x - c, y - r) <= 1.5
    image[blob] = FULL_SCALE
    return {"bleed_column": c, "bleed_rows": (max(r - half, 0), min(r + half + 1, rows))}


def wide_frame(seed: int, catalog, *, camera: int | None = None) -> WideFrame:
    """Draw frame ``seed`` of the class (module docstring); ``camera`` defaults to ``seed``."""
    cam = _camera(seed if camera is None else camera)
    rng = np.random.default_rng([5049, seed, 1])
    sensor = _sensor(cam)
    ra, dec = rng.uniform(0.0, 360.0), math.degrees(math.asin(rng.uniform(-1.0, 1.0)))
    att = attitude_from_radec_roll(*np.radians([ra, dec, rng.uniform(0.0, 360.0)]))
    fr = render_frame(sensor, att, catalog, rng=int(rng.integers(2**31)), noise=False)
    gain = sensor.detector.gain_counts_per_e
    rows, cols = cam["rows"], cam["columns"]
    noise = cam["read_noise_counts"]
    stray, s_info = _stray(rng, rows, cols, noise)
    counts = rng.poisson(np.maximum(fr.expected_e, 0.0)) * gain
    sky = rng.poisson(stray / gain) * gain  # the stray light's own photons
    image = 20.0 + counts + sky + noise * rng.standard_normal((rows, cols))
    image = np.clip(np.rint(image), 0, FULL_SCALE)
    hx, hy = cam["hot_xy"].T
    image[hy, hx] = np.maximum(image[hy, hx], np.rint(cam["hot_counts"]))
    b_info = _bleed(rng, image)
    stars = fr.truth.stars
    on = stars.on_detector
    star_counts = stars.electrons[on] * gain
    # matched-filter noise of an undersampled PSF: one pixel's at least (module docstring)
    psf_pixels = max(4 * math.pi * cam["psf_sigma_px"] ** 2, 1.0)
    snr = star_counts / (noise * math.sqrt(psf_pixels))
    xy = np.column_stack([stars.x_mid[on], stars.y_mid[on]])
    order = np.argsort(-star_counts, kind="stable")
    params = {
        "seed": seed,
        "camera": seed if camera is None else camera,
        "fov_deg": cam["fov_deg"],
        "columns": cols,
        "rows": rows,
        "psf_sigma_px": cam["psf_sigma_px"],
        "read_noise_counts": noise,
        "hot_pixels": len(hx),
        "stars_in_view": int(on.sum()),
        **s_info,
        **b_info,
    }
    return WideFrame(
        image.astype(np.uint16),
        att,
        math.radians(cam["fov_deg"]),
        params,
        int((snr >= EVIDENT_SNR).sum()),
        xy[order],
        cam["hot_xy"].astype(float),
    )
