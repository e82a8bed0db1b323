"""`solve --explain`, the per-stage counts, --bayer, and inputs that do not fit.

Frames are rendered (tests/_support/camera8.py: 6 x 4.5 deg, 1024 x 768, 8-bit) with a known
attitude; the bad inputs must each give one line naming what is wrong, exit 2, no traceback,
and no file left behind.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from camera8 import camera8, frame8

from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.geometry.attitude import radec_roll_from_attitude

COUNT_KEYS = {
    "pixels_above_threshold", "hot_pixels", "candidates", "rejected_size", "rejected_faint",
    "rejected_shape", "saturated", "detections", "patterns_tried", "hypotheses_verified",
    "best_false_match_probability",
}  # fmt: skip


@pytest.fixture(scope="module")
def frame(tmp_path_factory):
    from PIL import Image

    image, att, fr = frame8(camera8(), load_catalog("hipparcos"), 140.0, -20.0, 250.0, seed=3)
    folder = tmp_path_factory.mktemp("frames")
    Image.fromarray(image).save(folder / "f.png")
    stars = fr.truth.stars
    inside = (stars.x_mid > 0) & (stars.x_mid < 1023) & (stars.y_mid > 0) & (stars.y_mid < 767)
    order = np.argsort(stars.mag[inside])  # brightest first
    xy = np.column_stack([stars.x_mid[inside], stars.y_mid[inside]])[order]
    np.savetxt(folder / "c.csv", xy, delimiter=",", header="x,y", comments="")
    return folder, image, att


def _one_line_error(capsys, *parts):
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    for p in parts:
        assert p in err, err
    return err


@pytest.mark.slow
def test_explain_draws_a_solved_frame_and_the_json_has_the_counts(frame, tmp_path, capsys):
    folder, _, att = frame
    out = tmp_path / "why.png"
    args = ["solve", str(folder / "f.png"), "--fov-deg", "6", "--explain", str(out), "--json"]
    assert main(args) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["status"] == "solved" and payload["explain"] == str(out)
    c = payload["counts"]
    assert COUNT_KEYS <= set(c)
    # each stage keeps at most what the one before passed
    assert c["pixels_above_threshold"] >= c["candidates"] >= c["detections"] > 0
    rejected = c["rejected_size"] + c["rejected_faint"] + c["rejected_shape"]
    assert rejected == c["candidates"] - c["detections"]
    assert c["best_false_match_probability"] == payload["false_match_probability"]
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ra, dec, _ = np.degrees(radec_roll_from_attitude(att))
    assert math.isclose(payload["ra_deg"], ra, abs_tol=0.01)
    assert math.isclose(payload["dec_deg"], dec, abs_tol=0.01)


def test_explain_draws_a_failed_frame_with_its_reason(tmp_path, capsys):
    from PIL import Image

    rng = np.random.default_rng(1)
    image = np.clip(np.round(1.0 + 0.7 * rng.standard_normal((768, 1024))), 0, 255)
    image[100:103, 200:203] += 80  # three "stars": too few to solve
    image[400:403, 600:603] += 80
    image[600:603, 900:903] += 80
    Image.fromarray(image.astype(np.uint8)).save(tmp_path / "few.png")
    out = tmp_path / "why.png"
    args = ["solve", str(tmp_path / "few.png"), "--fov-deg", "6", "--explain", str(out)]
    assert main(args) == 1
    text = capsys.readouterr().out
    assert "not solved (too_few_stars)" in text and "candidates" in text
    assert out.is_file()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--bayer", "RGBG"], "--bayer must be one of RGGB, BGGR, GRBG, GBRG, got 'RGBG'"),
        (["--explain", "OUT.jpg"], "--explain writes a PNG figure"),
        (["--sensor", "st16"], "but the sensor 'st16' has a 2592 x 1944 detector"),
    ],
)
def test_bad_frame_options_are_one_line(frame, tmp_path, capsys, extra, message):
    folder, _, _ = frame
    extra = [str(tmp_path / e) if e.startswith("OUT") else e for e in extra]
    assert main(["solve", str(folder / "f.png"), *extra]) == 2
    _one_line_error(capsys, message)
    assert list(tmp_path.iterdir()) == []


def test_explain_and_bayer_refused_where_they_do_not_apply(frame, tmp_path, capsys):
    folder, _, _ = frame
    out = str(tmp_path / "x.png")
    assert main(["solve", str(folder), "--fov-deg", "6", "--explain", out]) == 2
    _one_line_error(capsys, "--explain draws one frame")
    cents = ["--centroids", str(folder / "c.csv"), "--image-size", "1024x768"]
    assert main(["solve", *cents, "--explain", out]) == 2
    _one_line_error(capsys, "--explain goes with a frame")
    assert main(["solve", *cents, "--bayer", "RGGB"]) == 2
    _one_line_error(capsys, "--bayer goes with a frame")
    assert list(tmp_path.iterdir()) == []


def test_centroids_outside_the_image_size_are_refused(frame, capsys):
    folder, _, _ = frame
    args = ["solve", "--centroids", str(folder / "c.csv"), "--image-size", "500x400"]
    assert main([*args, "--fov-deg", "6"]) == 2
    _one_line_error(capsys, str(folder / "c.csv"), "outside the 500 x 400 image")


def test_centroids_with_time_and_wcs(frame, tmp_path, capsys):
    from astropy.io import fits

    folder, _, att = frame
    out = tmp_path / "c.wcs"
    args = ["solve", "--centroids", str(folder / "c.csv"), "--image-size", "1024x768"]
    # a UTC offset: 22:47:26 at +02:00 is 20:47:26 UTC
    when = ["--time", "2019-07-29T22:47:26+02:00"]
    assert main([*args, "--fov-deg", "6", *when, "--wcs", str(out), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["apparent_places"]["applied"]
    assert payload["apparent_places"]["time_utc"].startswith("2019-07-29T20:47:26")
    header = fits.getheader(out)
    assert header["CTYPE1"].startswith("RA---TAN") and header["NAXIS"] == 0
    ra, dec, _ = np.degrees(radec_roll_from_attitude(att))
    # the rendered stars are catalogue places; the fit is to apparent places (aberration,
    # up to ~20 arcsec): the boresight within 30 arcsec of the render
    assert math.isclose(payload["ra_deg"], ra, abs_tol=30 / 3600 / math.cos(math.radians(dec)))
    assert math.isclose(payload["dec_deg"], dec, abs_tol=30 / 3600)


def test_bad_date_obs_names_the_file_and_the_card(frame, tmp_path, capsys):
    from astropy.io import fits

    _, image, _ = frame
    path = tmp_path / "f.fits"
    header = fits.Header()
    header["DATE-OBS"] = "2019-07-29T20:47:26"
    fits.PrimaryHDU(image.astype(np.int16), header=header).writeto(path)
    raw = path.read_bytes()
    i = raw.index(b"DATE-OBS")
    (tmp_path / "bad_value.fits").write_bytes(
        raw[:i] + b"DATE-OBS= 'last tuesday'".ljust(80) + raw[i + 80 :]
    )
    (tmp_path / "bad_card.fits").write_bytes(
        raw[:i] + b"DATE-OBS= 2019-07-29T20:47:26 unquoted".ljust(80) + raw[i + 80 :]
    )
    assert main(["solve", str(tmp_path / "bad_value.fits"), "--fov-deg", "6"]) == 2
    _one_line_error(capsys, "bad_value.fits: FITS DATE-OBS", "'last tuesday'")
    assert main(["solve", str(tmp_path / "bad_card.fits"), "--fov-deg", "6"]) == 2
    _one_line_error(capsys, "bad_card.fits: FITS card DATE-OBS")
    # a batch goes on: the frame's own status
    assert main(["solve", str(tmp_path / "bad_card.fits"), str(path), "--fov-deg", "6"]) == 1
    rows = capsys.readouterr().out.splitlines()
    assert rows[1].split(",")[1] == "unreadable" and rows[2].split(",")[1] == "solved"


def test_pillow_decompression_bomb_within_our_limit_is_read(frame, tmp_path, capsys, monkeypatch):
    from PIL import Image

    folder, _, _ = frame
    # Pillow refuses frames past twice its MAX_IMAGE_PIXELS as "decompression bombs"; ours is
    # the pixel limit (and its message), so a frame within it is read, in a batch of threads
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1000)
    paths = [str(folder / "f.png")] * 4
    assert main(["solve", *paths, "--fov-deg", "6", "--jobs", "2"]) == 0
    assert capsys.readouterr().out.count(",solved,") == 4
    assert Image.MAX_IMAGE_PIXELS == 1000  # left as it was
    monkeypatch.setenv("STARSENSE_MAX_PIXELS", "1000")
    assert main(["solve", str(folder / "f.png"), "--fov-deg", "6"]) == 2
    _one_line_error(capsys, "f.png: image of", "(786,432) is larger than the limit of 1,000")
