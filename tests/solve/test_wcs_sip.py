"""WCS of a solved frame through a distorting lens: TAN-SIP against the sensor model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from starsense.geometry.attitude import (
    attitude_from_radec_roll,
    radec_roll_from_attitude,
    radec_to_vectors,
    vectors_to_radec,
)
from starsense.sensor import load_sensor
from starsense.solve.solver import Solution
from starsense.solve.wcs import SIP_TOLERANCE_PX


def _solution(sensor):
    att = attitude_from_radec_roll(np.radians(200.0), np.radians(35.0), np.radians(25.0))
    ra, dec, roll = radec_roll_from_attitude(att)
    return Solution(
        "solved",
        ra_rad=float(ra),
        dec_rad=float(dec),
        roll_rad=float(roll),
        rotation=att,
        image_shape=(sensor.detector.rows, sensor.detector.columns),
        focal_px=sensor.focal_length_px,
        sensor=sensor,
    )


# a header-only WCS file (NAXIS = 0) makes astropy note that the image has fewer axes
@pytest.mark.filterwarnings("ignore::astropy.wcs.FITSFixedWarning")
@pytest.mark.parametrize("k1", [0.0, -0.4, 2.0])  # none, 2 % barrel, 10 % pincushion at corner
def test_sip_wcs_reproduces_the_sensor_model(k1, tmp_path):
    from astropy.io import fits
    from astropy.wcs import WCS

    base = load_sensor("st16")
    s = base.with_(
        optics=dataclasses.replace(
            base.optics,
            distortion_k1=k1,
            distortion_p1=2e-4 if k1 else 0.0,
            principal_offset_x_px=4.0,
            principal_offset_y_px=-3.0,
        )
    )
    sol = _solution(s)
    path = sol.write_wcs(tmp_path / "f.wcs.fits")
    header = fits.getheader(path)
    w = WCS(header)
    assert (w.sip is not None) == bool(k1)
    rng = np.random.default_rng(4)
    x = rng.uniform(-0.5, s.detector.columns - 0.5, 400)
    y = rng.uniform(-0.5, s.detector.rows - 0.5, 400)
    sky = sol.rotation.inv().apply(s.unproject(x, y))  # the sensor model: pixels -> ICRS
    ra, dec = vectors_to_radec(sky)
    # forward (A, B): pixels -> sky; FITS pixels are 1-based
    wra, wdec = w.all_pix2world(x + 1, y + 1, 1)
    got = radec_to_vectors(np.radians(wra), np.radians(wdec))
    err_arcsec = np.degrees(np.arccos(np.clip(np.sum(got * sky, axis=1), -1, 1))) * 3600
    # inverse (AP, BP): sky -> pixels
    px, py = w.all_world2pix(np.degrees(ra), np.degrees(dec), 1)
    err_px = np.hypot(px - 1 - x, py - 1 - y)
    # tolerance: the polynomial fit error the header reports (SIP_TOLERANCE_PX = 0.01 px on the
    # fitting grid; order 9 for 10 %), 0.01 px = 0.3 arcsec at ST-16's 28 arcsec pixels; the
    # random points between the grid nodes get 1.5x margin
    if k1:
        assert "largest fit error" in str(header["COMMENT"])
    assert np.max(err_px) < 1.5 * SIP_TOLERANCE_PX
    assert np.max(err_arcsec) < 0.45
