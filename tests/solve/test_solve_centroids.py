"""Solving lists of centroids (Solver.solve_centroids, `starsense solve --centroids`).

The convention is tested with a rendered frame whose truth gives the centroids: the renderer
projects every star through the sensor's pinhole (no distortion), so the truth positions are
exact pinhole positions and solving them must return the truth attitude to rounding. A
convention off by half a pixel would show as 0.5 px x 21 arcsec/px = 10 arcsec; one off by a
whole pixel (FITS 1-based) as 21 arcsec.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from camera8 import COLUMNS, FOV_RAD, ROWS, camera8

from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll, small_rotation_angles
from starsense.render.scene import render_frame
from starsense.solve.centroids import check_centroid_input
from starsense.solve.solver import Solver

ARCSEC_PER_RAD = 180 / math.pi * 3600
#: exact centroids: the attitude fit is limited by float64 rounding (~1e-9 rad); 0.05 arcsec
#: is 1/400 of a pixel and 200 times below the error of a half-pixel convention slip
EXACT_ARCSEC = 0.05


@pytest.fixture(scope="module")
def rendered():
    att = attitude_from_radec_roll(*np.radians([250.0, 30.0, 40.0]))
    frame = render_frame(camera8(), att, load_catalog("hipparcos"), noise=False, rng=0)
    return att, frame.truth.stars


@pytest.fixture(scope="module")
def truth(rendered):
    att, stars = rendered
    keep = stars.on_detector & (stars.mag < 8.5)
    order = np.argsort(-stars.electrons[keep])
    xy = np.column_stack([stars.x_mid[keep], stars.y_mid[keep]])[order]
    return att, xy, stars.electrons[keep][order]


def _error_arcsec(att, sol) -> float:
    return float(np.max(np.abs(small_rotation_angles(att, sol.rotation)))) * ARCSEC_PER_RAD


@pytest.mark.parametrize(
    "how", ["fov", "sensor", "fov_unknown"], ids=["fov_given", "sensor", "fov_searched"]
)
def test_truth_centroids_give_the_truth_attitude(truth, how):
    att, xy, flux = truth
    if how == "sensor":
        sol = Solver(sensor=camera8()).solve_centroids(xy, (COLUMNS, ROWS), brightness=flux)
    elif how == "fov":
        sol = Solver().solve_centroids(xy, (COLUMNS, ROWS), fov_rad=FOV_RAD, brightness=flux)
    else:
        sol = Solver().solve_centroids(xy, (COLUMNS, ROWS), brightness=flux)
    assert sol.solved, sol.message
    if how == "fov_unknown":
        # the field is found by the scale search: 6 deg to its fit's precision (1e-4 relative);
        # the attitude then carries the field's error (1e-4 x 3 deg at the edge = 1 arcsec)
        assert sol.fov_rad == pytest.approx(FOV_RAD, rel=1e-4)
        assert _error_arcsec(att, sol) < 1.0
    else:
        assert _error_arcsec(att, sol) < EXACT_ARCSEC
    assert sol.image_shape == (ROWS, COLUMNS)
    assert sol.ra_deg == pytest.approx(250.0, abs=1e-4) and sol.dec_deg == pytest.approx(30.0)
    np.testing.assert_array_equal(sol.centroids_px, xy)


def test_half_pixel_slip_is_seen(truth):
    # the test above can fail: the same centroids moved by half a pixel give ~10 arcsec
    att, xy, flux = truth
    sol = Solver().solve_centroids(xy + 0.5, (COLUMNS, ROWS), fov_rad=FOV_RAD, brightness=flux)
    assert sol.solved and _error_arcsec(att, sol) > 5.0


def test_listed_order_is_brightest_first(truth):
    att, xy, _ = truth
    sol = Solver().solve_centroids(xy[:25], (COLUMNS, ROWS), fov_rad=FOV_RAD)
    assert sol.solved and _error_arcsec(att, sol) < EXACT_ARCSEC


def test_fewer_than_three_centroids_is_a_status():
    sol = Solver().solve_centroids([[10.0, 20.0], [30.0, 40.0]], (640, 480), fov_rad=0.2)
    assert sol.status == "too_few_stars" and "2 centroid(s) given" in sol.message
    assert Solver().solve_centroids(np.zeros((0, 2)), (640, 480)).status == "too_few_stars"


def test_solve_centroids_checks_its_input():
    with pytest.raises(InputError, match=r"shape \(N, 2\)"):
        Solver().solve_centroids(np.zeros((4, 3)), (640, 480))
    with pytest.raises(InputError, match="centroid 1 is not finite"):
        Solver().solve_centroids([[1, 2], [np.nan, 3], [4, 5]], (640, 480))
    with pytest.raises(InputError, match="brightness must be 3 finite numbers"):
        Solver().solve_centroids([[1, 2], [2, 3], [4, 5]], (640, 480), brightness=[1, 2])
    with pytest.raises(InputError, match="image_size 640 x 480 is not the sensor's 1024 x 768"):
        Solver(sensor=camera8()).solve_centroids([[1, 2], [2, 3], [4, 5]], (640, 480))
    with pytest.raises(InputError, match="image width must be an integer"):
        Solver().solve_centroids([[1, 2], [2, 3], [4, 5]], (640.5, 480))


def test_edge_stars_up_to_two_pixels_outside_are_kept(rendered):
    # The same sky seen by a narrower image: the frame cropped by 9 px on the left and on the
    # right keeps its centre, so it is the pinhole of the same focal length, fov' from the
    # cropped width. The star 7.76 px from the left edge then lies 1.24 px left of the cropped
    # image's first pixel centre (0.74 px beyond its edge): an edge star, as an extractor
    # reports one cut by the edge. Its exact position must be used, to rounding.
    att, stars = rendered
    crop = 9
    width = COLUMNS - 2 * crop
    focal_px = (COLUMNS / 2) / math.tan(FOV_RAD / 2)
    fov = 2 * math.atan((width / 2) / focal_px)
    xy = np.column_stack([stars.x_mid - crop, stars.y_mid])
    lo, hi = -0.5 - 2.0, np.array([width, ROWS]) - 0.5 + 2.0
    keep = (stars.mag < 8.5) & np.all((xy >= lo) & (xy <= hi), axis=1)
    xy, flux = xy[keep], stars.electrons[keep]
    edge = (xy[:, 0] < -0.5).sum()
    assert edge == 1  # the test is about it: one star outside the cropped image
    sol = Solver().solve_centroids(xy, (width, ROWS), fov_rad=fov, brightness=flux)
    assert sol.solved, sol.message
    assert _error_arcsec(att, sol) < EXACT_ARCSEC
    assert int(np.argmin(xy[:, 0])) in {m[0] for m in sol.matches}  # the edge star is identified


def test_centroids_more_than_two_pixels_outside_are_refused(rendered):
    # the full set of the uncropped frame holds a star 2.89 px below the last row's centre
    # (2.39 px beyond the edge): farther than an edge star, so the image size is in question
    _, stars = rendered
    keep = stars.mag < 8.5
    xy = np.column_stack([stars.x_mid[keep], stars.y_mid[keep]])
    assert xy[:, 1].max() - (ROWS - 0.5) > 2.0
    with pytest.raises(InputError, match=r"outside the 1024 x 768 image by more than 2 px"):
        Solver().solve_centroids(xy, (COLUMNS, ROWS), fov_rad=FOV_RAD)


@pytest.mark.parametrize(
    ("x", "y", "ok"),
    [
        (-2.5, 10.0, True),  # 2 px beyond the left edge (-0.5): the limit, kept
        (639.5 + 2.0, 10.0, True),  # 2 px beyond the right edge (639.5)
        (10.0, 479.5 + 2.0, True),
        (10.0, -2.5, True),
        (-2.5 - 1e-6, 10.0, False),
        (641.5 + 1e-6, 10.0, False),
        (10.0, -2.51, False),
        (10.0, 481.6, False),
    ],
)
def test_edge_margin_is_two_pixels_beyond_the_image_edge(x, y, ok):
    xy = np.array([[100.0, 100.0], [300.0, 200.0], [x, y]])
    if ok:
        assert check_centroid_input(xy, (640, 480))[0][2].tolist() == [x, y]
    else:
        with pytest.raises(InputError, match=r"1 centroid\(s\) lie outside the 640 x 480 image"):
            check_centroid_input(xy, (640, 480))


# -- files and the command line -----------------------------------------------------------------


def _write_csv(path, xy, flux=None, header=None):
    lines = [] if header is None else [header]
    for i, (x, y) in enumerate(xy):
        lines.append(f"{x!r},{y!r}" + ("" if flux is None else f",{flux[i]!r}"))
    path.write_text("\n".join(lines) + "\n")
    return path


def _cli(argv, capsys):
    code = main(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_csv_and_xylist_give_the_truth_attitude(truth, tmp_path, capsys):
    from astropy.io import fits

    att, xy, flux = truth
    # CSV with a header in another column order, and the flux shuffled with the rows
    order = np.random.default_rng(1).permutation(len(xy))
    csv = tmp_path / "c.csv"
    rows = [f"{float(flux[i])!r},{float(xy[i, 1])!r},{float(xy[i, 0])!r}" for i in order]
    csv.write_text("FLUX,Y,X\n" + "\n".join(rows) + "\n")
    # xylist: FITS pixels, first centre at (1, 1), image size in the header
    cols = [
        fits.Column(name=n, format="D", array=a)
        for n, a in (("X", xy[:, 0] + 1), ("Y", xy[:, 1] + 1), ("FLUX", flux))
    ]
    hdu = fits.BinTableHDU.from_columns(cols)
    hdu.header["IMAGEW"], hdu.header["IMAGEH"] = COLUMNS, ROWS
    xyls = tmp_path / "c.xyls"
    fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(xyls)
    for path, size in ((csv, ["--image-size", f"{COLUMNS}x{ROWS}"]), (xyls, [])):
        argv = ["solve", "--centroids", str(path), *size, "--fov-deg", "6", "--json"]
        code, out, err = _cli(argv, capsys)
        assert code == 0, err
        got = json.loads(out)
        assert got["status"] == "solved" and got["centroids"] == str(path)
        sol = attitude_from_radec_roll(
            *np.radians([got["ra_deg"], got["dec_deg"], got["roll_deg"]])
        )
        err_arcsec = np.abs(small_rotation_angles(att, sol)) * ARCSEC_PER_RAD
        assert np.all(err_arcsec < EXACT_ARCSEC), (path.suffix, err_arcsec)


def test_cli_centroid_bad_input(tmp_path, capsys):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    code, out, err = _cli(["solve", "--centroids", str(empty), "--image-size", "640x480"], capsys)
    assert code == 2 and err.count("\n") == 1 and "no centroids (the file is empty)" in err
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y\n1.0,2.0\n3.0,abc\n")
    code, out, err = _cli(["solve", "--centroids", str(bad), "--image-size", "640x480"], capsys)
    assert code == 2 and "line 3, column 2: not a number: 'abc'" in err and "Traceback" not in err
    two = _write_csv(tmp_path / "two.csv", [(1.0, 2.0), (30.0, 40.0)])
    argv = ["solve", "--centroids", str(two), "--image-size", "640x480", "--json"]
    code, out, err = _cli(argv, capsys)
    assert code == 1 and json.loads(out)["status"] == "too_few_stars"
    code, out, err = _cli(["solve", "--centroids", str(two)], capsys)
    assert code == 2 and "--image-size WIDTHxHEIGHT is needed" in err
    code, out, err = _cli(["solve", "--centroids", str(two), "--image-size", "640by480"], capsys)
    assert code == 2 and "--image-size must be WIDTHxHEIGHT" in err


def _random_points(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform([0.0, 0.0], [COLUMNS - 1.0, ROWS - 1.0], size=(20, 2))


def test_a_set_that_identifies_nowhere_stops_at_the_solves_budget():
    # random points: every attempt of the solve (the field given as an estimate, the scale
    # search, the distortion guesses, the mirror) fails; the budget, summed over them, stops
    # the solve at the same pattern every time (deterministic, whatever the machine's load)
    for budget in (50, 700, 2000):
        solver = Solver(fov_rad=FOV_RAD, max_patterns=budget)
        first = solver.solve_centroids(_random_points(1), (COLUMNS, ROWS))
        assert first.status == "timeout", first.message
        assert f"work budget of one solve, {budget} patterns" in first.message
        again = solver.solve_centroids(_random_points(1), (COLUMNS, ROWS))
        assert (again.status, again.message, again.counts) == (
            first.status,
            first.message,
            first.counts,
        )
    # without a bound the same points go through every attempt and end as no match
    free = Solver(fov_rad=FOV_RAD, max_patterns=None).solve_centroids(
        _random_points(1), (COLUMNS, ROWS)
    )
    assert free.status == "no_match"


def test_the_default_budget_leaves_solvable_sets_as_they_were(truth):
    _att, xy, flux = truth
    bounded = Solver(fov_rad=FOV_RAD).solve_centroids(xy, (COLUMNS, ROWS), brightness=flux)
    free = Solver(fov_rad=FOV_RAD, max_patterns=None).solve_centroids(
        xy, (COLUMNS, ROWS), brightness=flux
    )
    assert bounded.solved and bounded.matches == free.matches
    assert bounded.ra_rad == free.ra_rad and bounded.roll_rad == free.roll_rad


@pytest.mark.parametrize("bad", [0, -5, 2.5, "many", True])
def test_a_budget_that_is_not_a_positive_count_is_refused(bad):
    with pytest.raises(InputError, match="max_patterns"):
        Solver(fov_rad=FOV_RAD, max_patterns=bad)
