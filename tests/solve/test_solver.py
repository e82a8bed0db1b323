"""The full pipeline on real frames: image -> detection -> identification -> attitude.

Acceptance: the eight ESA frames solve, each boresight within 15 arcsec of
reference.json (cedar-solve's solution, itself fitted to 5-7 arcsec rms; LOST agrees to ~10).
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.detect import StarDetector
from starsense.errors import InputError
from starsense.geometry.attitude import (
    angular_separation,
    attitude_from_radec_roll,
    radec_to_vectors,
    small_rotation_angles,
)
from starsense.identify import HashIdentifier, build_database, fields, identify_ranked
from starsense.render.io import write_frame
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve import identifiers
from starsense.solve.frames import load_image
from starsense.solve.pinhole import pinhole_vectors
from starsense.solve.solver import Solution, Solver

ARCSEC_PER_RAD = 180 / math.pi * 3600
INTERFACE_KEYS = {
    "status", "ra_deg", "dec_deg", "roll_deg", "fov_deg", "n_matched", "rmse_arcsec",
    "false_match_probability", "time_ms",
}  # fmt: skip


@pytest.fixture(scope="module")
def esa(shared_dir):
    folder = shared_dir / "data" / "images" / "esa"
    return folder, json.loads((folder / "reference.json").read_text())["frames"]


def _separation_arcsec(sol, ref) -> float:
    a = radec_to_vectors(math.radians(sol["ra_deg"]), math.radians(sol["dec_deg"]))
    b = radec_to_vectors(math.radians(ref["ra_deg"]), math.radians(ref["dec_deg"]))
    return float(angular_separation(a, b)) * ARCSEC_PER_RAD


@pytest.mark.parametrize(
    "optics",
    [{"sensor": "esa_blackfly"}, {"fov_rad": math.radians(11.42)}, {}],
    ids=["sensor", "fov", "none"],
)
def test_esa_frames_solve_within_15_arcsec(esa, optics):
    # with matched-filter detection and the optics known, every boresight within
    # 6 arcsec (measured: 4.2 with the sensor); found by the scale search, within 15 (6.0;
    # 6.6 before matched-filter detection)
    folder, reference = esa
    solver = Solver(**optics)
    bound = 6 if optics else 15
    for name, ref in reference.items():
        sol = solver.solve_file(folder / name).to_dict()
        assert sol["status"] == "solved", (name, sol["message"])
        assert _separation_arcsec(sol, ref) < bound, name
        droll = (sol["roll_deg"] - ref["roll_deg"] + 180) % 360 - 180
        assert abs(droll) < 0.05, name  # 0.05 deg = 3 arcmin: roll is the weak axis
        # the field: the reference fits give 11.422-11.425 deg; 0.1 % when it is searched
        assert sol["fov_deg"] == pytest.approx(ref["fov_deg"], rel=1e-3)
        assert sol["false_match_probability"] < 1e-20
        assert sol["rmse_arcsec"] < 30  # measured 10-16 arcsec (40 arcsec pixels)


def test_solve_cli_json_interface(esa, capsys):
    folder, reference = esa
    name = next(iter(reference))
    code = main(["solve", str(folder / name), "--sensor", "esa_blackfly", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert INTERFACE_KEYS <= set(out)
    assert out["status"] == "solved"
    assert out["n_matched"] >= 0.8 * reference[name]["matched_stars"]


def test_solve_rendered_frame_round_trip(tmp_path, capsys):
    # render an ST-16 frame at a known attitude, write it, solve it from the file
    sensor = load_sensor("st16")
    truth = attitude_from_radec_roll(math.radians(83.8), math.radians(-5.4), math.radians(30))
    frame = render_frame(sensor, truth, load_catalog("hipparcos"), max_mag=6.5, rng=5)
    path = write_frame(tmp_path / "f.tiff", frame)
    sol = Solver(sensor="st16").solve_file(path)
    assert sol.solved, sol.message
    err = small_rotation_angles(truth, sol.rotation) * ARCSEC_PER_RAD
    # cross-boresight error: centroids of ~0.03 px (x 28 arcsec/px) over ~20 stars -> < 1 arcsec;
    # allow 3 arcsec; roll (weak axis, lever arm ~ half the field) 30 arcsec
    assert np.all(np.abs(err[:2]) < 3) and abs(err[2]) < 30


def test_solve_no_stars_is_a_one_line_error(tmp_path, capsys):
    from PIL import Image

    Image.fromarray(np.full((100, 120), 500, np.uint16)).save(tmp_path / "empty.tiff")
    code = main(["solve", str(tmp_path / "empty.tiff"), "--fov-deg", "10"])
    err = capsys.readouterr().err
    assert code == 2
    assert "no star passed the detection logic" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--sensor", "st16", "--fov-deg", "10"], "give --sensor or --fov-deg, not both"),
        (["--fov-deg", "300"], r"--fov-deg must be within \[0.5, 120\] deg"),
        (["--algorithm", "triangle"], "the triangle algorithm needs a known field"),
    ],
)
def test_solve_bad_options(tmp_path, capsys, argv, message):
    code = main(["solve", str(tmp_path / "x.tiff"), *argv])
    assert code == 2
    assert re.search(message, capsys.readouterr().err)


@pytest.mark.parametrize("rough_fov_deg", [10.0, 12.5])
@pytest.mark.slow
def test_rough_fov_is_refined(esa, rough_fov_deg):
    # optics known only to ~10 %: the scale search around the estimate finds the field
    folder, reference = esa
    name, ref = next(iter(reference.items()))
    sol = Solver(fov_rad=math.radians(rough_fov_deg)).solve_file(folder / name).to_dict()
    assert sol["status"] == "solved"
    assert sol["fov_deg"] == pytest.approx(ref["fov_deg"], rel=1e-3)
    assert _separation_arcsec(sol, ref) < 15


# a header-only WCS file (NAXIS = 0, as astrometry.net's .wcs files) makes astropy note that the
# WCS has more axes than the (absent) image: expected, not a defect of the file
@pytest.mark.filterwarnings("ignore::astropy.wcs.FITSFixedWarning")
def test_wcs_maps_matched_stars_onto_the_catalogue(esa, tmp_path, capsys):
    # The TAN WCS is exact for a pinhole: matched centroids mapped through it must land on their
    # catalogue stars within the solution's own residuals (11 arcsec rms on 40 arcsec pixels);
    # a flipped or mis-rotated CD matrix would put them degrees away.
    from astropy.io import fits
    from astropy.wcs import WCS

    folder, reference = esa
    name = next(iter(reference))
    out = tmp_path / "sol.wcs.fits"
    assert main(["solve", str(folder / name), "--sensor", "esa_blackfly", "--wcs", str(out)]) == 0
    wcs = WCS(fits.getheader(out))
    sol = Solver(sensor="esa_blackfly").solve_file(folder / name)
    det = np.array([d for d, _ in sol.matches])
    ids = np.array([c for _, c in sol.matches])
    xy = sol.centroids_px[det]
    ra, dec = wcs.all_pix2world(xy[:, 0] + 1, xy[:, 1] + 1, 1)  # FITS pixels are 1-based
    cat = load_catalog("hipparcos")
    sep = angular_separation(
        radec_to_vectors(np.radians(ra), np.radians(dec)), cat.vectors[cat.index_of(ids)]
    )
    assert np.median(sep) * ARCSEC_PER_RAD < 20
    assert np.max(sep) * ARCSEC_PER_RAD < 60


def test_identification_does_not_depend_on_centroid_order(esa):
    # Shuffle the detections: the same stars must be identified and the same attitude found,
    # and the match indices must follow the shuffled order.
    folder, reference = esa
    sensor = load_sensor("esa_blackfly")
    det = StarDetector(sensor.detection, background="auto", threshold_sigma=5)(
        load_image(folder / next(iter(reference)))
    )
    fov = 2 * sensor.half_fov_rad[0]
    identify = HashIdentifier(build_database(load_catalog("hipparcos"), fov))
    v = sensor.unproject(det.x, det.y)
    flux = det.integrated_counts
    base = identify_ranked(identify, v, flux, fov)
    rng = np.random.default_rng(0)
    for _ in range(3):
        order = rng.permutation(len(v))
        res = identify_ranked(identify, v[order], flux[order], fov)
        assert res.solved
        # detection k of the shuffled list is detection order[k] of the original
        pairs = {
            (int(order[d]), int(c))
            for d, c in zip(res.detection_index, res.catalog_id, strict=True)
        }
        assert pairs == set(
            zip(base.detection_index.tolist(), base.catalog_id.tolist(), strict=True)
        )
        angle = np.linalg.norm(small_rotation_angles(base.rotation, res.rotation))
        assert angle * ARCSEC_PER_RAD < 1.0  # same solution (refits differ only by rounding)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pure_noise_frame_returns_no_solution(seed):
    # Gaussian noise on a flat background: whatever the detector picks up, the verifier must
    # refuse (false-match probability not small), never return a wrong attitude or raise.
    rng = np.random.default_rng(seed)
    image = np.clip(rng.normal(3000, 150, (768, 1024)), 0, 65535).astype(np.uint16)
    # a few random "stars" of noise-like blobs, so identification is actually attempted
    for x, y in rng.uniform([20, 20], [1000, 750], (25, 2)):
        image[int(y) - 1 : int(y) + 2, int(x) - 1 : int(x) + 2] += 2500
    sol = Solver(sensor="esa_blackfly")(image)
    assert sol.status != "solved"
    assert sol.rotation is None


def test_pinhole_vectors_centre_and_edge():
    # principal point at the image centre (pixel-centre convention); the left and right edges
    # of the image (x = -0.5 and cols - 0.5) lie at half the horizontal field from the boresight
    fov = math.radians(12.0)
    rows, cols = 480, 640
    v = pinhole_vectors(
        [(cols - 1) / 2, -0.5, cols - 0.5], [(rows - 1) / 2] * 3, shape=(rows, cols), fov_rad=fov
    )
    assert v.shape == (3, 3)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(v[0], [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(np.arccos(v[1:, 2]), fov / 2, rtol=1e-12)
    assert v[1, 0] < 0 < v[2, 0]  # +x towards increasing column


def test_solver_checks_its_parameters_by_name():
    with pytest.raises(InputError, match="give sensor or fov_rad, not both"):
        Solver(sensor="st16", fov_rad=0.2)
    with pytest.raises(InputError, match=r"fov_rad = 5.0 is out of range"):
        Solver(fov_rad=5.0)
    with pytest.raises(InputError, match="the triangle algorithm needs a known field"):
        Solver(algorithm="triangle")
    with pytest.raises(InputError, match=r"centroid_sigma_px must be > 0 or 'snr', got -1\.0"):
        Solver(fov_rad=0.2, centroid_sigma_px=np.float64(-1.0))


def test_solution_stores_radians_and_shows_degrees():
    sigma = (1e-5, 2e-5, 3e-5)
    sol = Solution(
        "solved",
        ra_rad=math.pi / 2,
        dec_rad=-math.pi / 4,
        roll_rad=0.0,
        fov_rad=math.radians(10),
        rmse_rad=1e-5,
        sigma_rad=sigma,
    )
    d = sol.to_dict()
    assert d["ra_deg"] == pytest.approx(90.0) and d["dec_deg"] == pytest.approx(-45.0)
    assert d["fov_deg"] == pytest.approx(10.0)
    assert d["rmse_arcsec"] == pytest.approx(1e-5 * ARCSEC_PER_RAD)
    assert d["sigma_arcsec"] == pytest.approx([s * ARCSEC_PER_RAD for s in sigma])
    empty = Solution("no_stars").to_dict()
    assert empty["ra_deg"] is None and empty["sigma_arcsec"] is None


@pytest.mark.slow
def test_solver_takes_a_catalog_object(esa, monkeypatch):
    # a catalogue filtered in Python (V <= 6.5: 8,918 Hipparcos stars) is carried, not
    # reloaded: every range of the unknown-field search uses it, and the ESA frames solve
    # within the bounds of test_esa_frames_solve_within_15_arcsec without optics (measured:
    # 0.4-5.3 arcsec)
    hipparcos = load_catalog("hipparcos")
    bright = hipparcos.subset(hipparcos.mags["V"] <= 6.5)

    def no_reload(spec):
        raise AssertionError(f"catalogue {spec!r} loaded again")

    monkeypatch.setattr(fields, "load_catalog", no_reload)
    monkeypatch.setattr(identifiers, "load_catalog", no_reload)
    folder, reference = esa
    solver = Solver(catalog=bright)
    assert solver.catalog is bright and solver.settings.catalog is bright
    assert all(r.catalog is bright for r in solver.field_plan())
    for name, ref in reference.items():
        sol = solver.solve_file(folder / name).to_dict()
        assert sol["status"] == "solved", (name, sol["message"])
        assert _separation_arcsec(sol, ref) < 15, name
        droll = (sol["roll_deg"] - ref["roll_deg"] + 180) % 360 - 180
        assert abs(droll) < 0.05, name
        assert sol["fov_deg"] == pytest.approx(ref["fov_deg"], rel=1e-3)
