"""A seeded family of wide-field frames through a 3 mm lens with strong radial distortion.

The camera: a Raspberry Pi camera V2 class module (Sony IMX219, 1.12 um pixels read out 2x2
binned to 2.24 um, f = 3.04 mm, f/2.0: the Raspberry Pi camera documentation), 8-bit JPEG. A
field of F deg is the centred crop of ``2 f tan(F/2) / 2.24 um`` columns (60 deg is about the
whole binned sensor, 1640 px; 4:3).

The distortion (Brown-Conrady, tangent-plane units of the focal length, as
:mod:`starsense.geometry.distortion`) is drawn per frame between two physical ends:

* the published calibration of this camera (UbiquityRobotics raspicam_node,
  ``camera_info/camerav2_1280x960.yaml``, OpenCV plumb-bob): k1 = 0.1350, k2 = -0.2336,
  p1 = 0.00067, p2 = 0.00485, principal point (15.9, 10.6) px from the centre of 1280 x 960 at
  f = 1006 px;
* an equidistant (f-theta) lens, the projection short fisheye-like lenses follow: r_d = atan(r)
  = r (1 - r^2/3 + r^4/5 - ...), i.e. k1 = -1/3, k2 = +1/5: barrel distortion of -9 % at 30 deg
  off axis and -13 % in the corners of a 60 deg field.

Each frame takes ``k = (1 - t) k_calibrated + t k_equidistant`` with t uniform in [0, 1] (so
about half the frames are strongly barrel-distorted), the calibration's decentring terms scaled
by a uniform factor in [-1, 1] and a principal-point offset of up to the calibration's, at a
uniform random attitude, with an exposure log-uniform in 1-4 s (from tens to hundreds of
stars detected) and a sky glow of 0-200 e- per pixel and second.
"""

from __future__ import annotations

import io
import math

import numpy as np

from starsense.catalog.table import Catalog
from starsense.geometry.sampling import random_attitudes
from starsense.render.noise import apply_noise
from starsense.render.scene import render_frame
from starsense.sensor.load import sensor_from_dict

FOCAL_M = 3.04e-3
PITCH_M = 2.24e-6
APERTURE_M = FOCAL_M / 2.0
#: the published Pi camera V2 calibration (raspicam_node camerav2_1280x960.yaml)
PI_V2 = {"k1": 0.1349735, "k2": -0.2335870, "p1": 0.000669703, "p2": 0.00484674}
PI_V2_PRINCIPAL_OFFSET_PX = (655.864 - 639.5, 490.614 - 479.5)  # at f = 1006 px
#: the equidistant (f-theta) projection as a radial series: atan(r)/r = 1 - r^2/3 + r^4/5
EQUIDISTANT = {"k1": -1.0 / 3.0, "k2": 1.0 / 5.0}


def wide_sensor(fov_deg: float, *, k1=0.0, k2=0.0, p1=0.0, p2=0.0, offset_px=(0.0, 0.0)):
    """The camera with a field of ``fov_deg`` across its columns and the given distortion."""
    columns = round(2 * FOCAL_M * math.tan(math.radians(fov_deg) / 2) / PITCH_M)
    rows = round(columns * 0.75)
    return sensor_from_dict(
        {
            "name": f"pi_v2_{fov_deg:g}deg",
            "exposure_s": 4.0,
            "optics": {
                "focal_length_m": FOCAL_M,
                "aperture_m": APERTURE_M,
                "transmission": 0.8,
                "distortion_k1": k1,
                "distortion_k2": k2,
                "distortion_p1": p1,
                "distortion_p2": p2,
                "principal_offset_x_px": offset_px[0],
                "principal_offset_y_px": offset_px[1],
            },
            "detector": {
                "columns": columns,
                "rows": rows,
                "pixel_pitch_m": PITCH_M,
                "bit_depth": 8,
                "gain_counts_per_e": 0.1,
                "read_noise_e": 10.0,
                "psf_sigma_px": 1.0,
                "qe_mean": 0.5,
                "bias_counts": 6.0,
                "full_well_e": 20000.0,
            },
            "detection": {"lit_pixel_counts": 3.0, "min_pixels": 3, "min_integrated_counts": 0.0},
        }
    )


def draw_lens(fov_deg: float, rng: np.random.Generator):
    """Draw one lens of the family (module docstring); return its Sensor and its parameters."""
    t = rng.uniform(0.0, 1.0)
    k1 = (1 - t) * PI_V2["k1"] + t * EQUIDISTANT["k1"]
    k2 = (1 - t) * PI_V2["k2"] + t * EQUIDISTANT["k2"]
    p1, p2 = rng.uniform(-1.0, 1.0, 2) * (PI_V2["p1"], PI_V2["p2"])
    # the calibration's principal-point offset scaled to this field's focal length in pixels
    scale = FOCAL_M / PITCH_M / 1006.126
    offset = tuple(rng.uniform(-1.0, 1.0, 2) * np.array(PI_V2_PRINCIPAL_OFFSET_PX) * scale)
    lens = {"k1": k1, "k2": k2, "p1": p1, "p2": p2, "offset_px": offset}
    return wide_sensor(fov_deg, **lens), lens


def wide_frame(fov_deg: float, seed: int, catalog: Catalog, *, jpeg_quality: int = 90):
    """Render one frame of the family: (uint8 image, truth attitude, Frame, Sensor, lens dict)."""
    rng = np.random.default_rng([round(fov_deg * 1000), seed])
    sensor, lens = draw_lens(fov_deg, rng)
    att = random_attitudes(1, rng)[0]
    exposure_s = float(np.exp(rng.uniform(np.log(1.0), np.log(4.0))))
    sky_e = rng.uniform(0.0, 200.0) * exposure_s  # sky glow, e- per pixel
    fr = render_frame(
        sensor, att, catalog, rng=rng, noise=False, max_mag=7.5, exposure_s=exposure_s
    )
    image = apply_noise(fr.expected_e + sky_e, sensor, rng=rng)
    image = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    if jpeg_quality is not None:
        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(image).save(buf, format="JPEG", quality=jpeg_quality)
        buf.seek(0)
        image = np.array(Image.open(buf))
    return image, att, fr, sensor, lens
