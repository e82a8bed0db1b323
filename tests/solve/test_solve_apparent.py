"""Apparent places in the loop: a frame rendered as a real camera sees the sky
at a given time solves to the true ICRS attitude only with the correction on."""

from __future__ import annotations

import json

import numpy as np
import pytest

from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.geometry.apparent import observer_state
from starsense.geometry.attitude import (
    attitude_from_radec_roll,
    small_rotation_angles,
    vectors_to_radec,
)
from starsense.render.io import write_frame
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.solver import Solver
from starsense.units import ARCSEC

T = "2026-03-21T12:00:00"


@pytest.fixture(scope="module")
def scene():
    # Point 90 deg from the Earth's velocity, where the aberration (20.5 arcsec there) is largest
    # and nearly uniform over the field: it moves the whole field, i.e. the boresight.
    _, v = observer_state(T)
    apex = v / np.linalg.norm(v)
    b = np.cross(apex, [0.0, 0.0, 1.0])
    b /= np.linalg.norm(b)
    ra, dec = vectors_to_radec(b)
    att = attitude_from_radec_roll(float(ra), float(dec), 0.4)
    frame = render_frame(_st16(), att, load_catalog("hipparcos"), rng=3, obs_time=T)
    return att, frame


def _st16():
    return load_sensor("st16")


def _pointing_error_arcsec(att, sol) -> float:
    return float(np.hypot(*small_rotation_angles(att, sol.rotation)[:2]) / ARCSEC)


def test_aberrated_frame_solves_to_the_truth_only_with_the_correction(scene):
    att, frame = scene
    solver = Solver("st16", centroid_sigma_px="snr")
    on = solver(frame.image, T)
    off = solver(frame.image)
    assert on.solved and off.solved
    sigma = float(np.hypot(*on.sigma_arcsec[:2]))  # predicted 1-sigma pointing error (~1.7")
    # with the correction: at the noise level (3 sigma of the predicted covariance)
    assert _pointing_error_arcsec(att, on) < 3 * sigma
    # without: off by the aberration, |v| / c = 20.6 arcsec here. Over the 20-deg field the
    # aberration is not a rigid rotation (it differs by up to |v| / c x 0.17 rad = 3.5 arcsec
    # across it), so the weighted fit and its roll take up part: measured 14.7 arcsec, and
    # 19.9 for an unweighted fit. 10 arcsec is still > 5 sigma of the predicted noise.
    assert _pointing_error_arcsec(att, off) > max(10.0, 5 * sigma)
    assert on.to_dict()["apparent_places"]["applied"] is True
    assert off.to_dict()["apparent_places"] == {"applied": False, "reason": "no frame time"}


@pytest.mark.parametrize("ext", ["tiff", "fits"])
def test_frame_time_read_from_the_file_and_reported(scene, tmp_path, capsys, ext):
    _, frame = scene
    path = write_frame(tmp_path / f"f.{ext}", frame)
    assert main(["solve", str(path), "--sensor", "st16", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ap = out["apparent_places"]
    assert ap["applied"] and ap["time_utc"].startswith(T)
    assert ap["time_source"] == ("FITS DATE-OBS" if ext == "fits" else "EXIF DateTime")
    assert ap["observer_speed_km_s"] == pytest.approx(29.9, abs=0.6)  # Earth orbit, 29.3-30.3
    # --no-apparent turns it off, and the pointing moves by the aberration
    assert main(["solve", str(path), "--sensor", "st16", "--json", "--no-apparent"]) == 0
    off = json.loads(capsys.readouterr().out)
    assert off["apparent_places"]["applied"] is False
    shift = np.hypot(out["ra_deg"] - off["ra_deg"], out["dec_deg"] - off["dec_deg"]) * 3600
    assert shift > 10.0  # arcsec (as above); Dec = 0 here, so no cos(Dec) is needed


def test_time_option_and_bad_time(scene, tmp_path, capsys):
    _, frame = scene
    path = write_frame(tmp_path / "f.png", frame)
    assert main(["solve", str(path), "--sensor", "st16", "--json", "--time", T]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["apparent_places"]["time_source"] == "--time"
    assert main(["solve", str(path), "--sensor", "st16", "--time", "noon"]) == 2
    err = capsys.readouterr().err
    assert "ISO 8601" in err and "Traceback" not in err


def test_render_time_option_writes_the_time(tmp_path, capsys):
    out = tmp_path / "f.fits"
    args = ["render", "--sensor", "st16", "--ra-deg", "83.8", "--dec-deg", "-5.4", "--seed", "1"]
    assert main([*args, "--time", T, "--out", str(out)]) == 0
    from astropy.io import fits

    assert fits.getheader(out)["DATE-OBS"].startswith(T)
    truth = json.loads((tmp_path / "f.fits.json").read_text())
    assert truth["apparent_places"]["applied"] and truth["apparent_places"]["aberration"]
    capsys.readouterr()
    bad = tmp_path / "g.fits"
    assert main([*args, "--time", "2026-13-01T00:00:00", "--out", str(bad)]) == 2
    assert "--time must be an ISO 8601" in capsys.readouterr().err
    assert not bad.exists()
