"""`solve --json`: the attitude as a quaternion (scalar last, ICRS -> camera) and a matrix, the
sigmas by axis name; the same in a batch's lines.

The frame is rendered (tests/_support/camera8.py: 6 x 4.5 deg, 1024 x 768, 8-bit) at a known
attitude.
"""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest
from camera8 import camera8, frame8
from scipy.spatial.transform import Rotation

from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.cli.attitude_json import attitude_fields
from starsense.solve.solution import Solution
from starsense.solve.solver import Solver
from starsense.units import ARCSEC, DEG


@pytest.fixture(scope="module")
def validator():
    jsonschema = pytest.importorskip("jsonschema", reason="jsonschema is in the dev extra")
    schema = json.loads((resources.files("starsense") / "data" / "solve.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.fixture(scope="module")
def frame(tmp_path_factory):
    from PIL import Image

    image, att, _ = frame8(camera8(), load_catalog("hipparcos"), 140.0, -20.0, 250.0, seed=3)
    folder = tmp_path_factory.mktemp("frames")
    Image.fromarray(image).save(folder / "f.png")
    return folder / "f.png", att


def test_quaternion_matrix_and_labelled_sigmas(frame, validator, capsys):
    path, truth = frame
    assert main(["solve", str(path), "--fov-deg", "6", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["status"] == "solved"
    validator.validate(d)  # the documented schema (solve --schema)
    q = np.array(d["quaternion_xyzw"])
    assert q.shape == (4,) and q[3] >= 0.0
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)  # a unit quaternion
    rot = Rotation.from_quat(q)  # scipy's order: scalar last
    # the matrix is the same rotation (float round-off only)
    assert np.allclose(rot.as_matrix(), d["rotation_matrix"], atol=1e-12)
    # the Python Solution gives the same rotation, in the same convention
    sol = Solver(None, fov_rad=6 * DEG).solve_file(path)
    assert (rot.inv() * sol.rotation).magnitude() < 1e-9
    # ICRS -> camera: the camera's +z (boresight) maps back to the RA/Dec the line prints
    boresight = rot.inv().apply([0.0, 0.0, 1.0])
    ra, dec = np.radians(d["ra_deg"]), np.radians(d["dec_deg"])
    icrs = [np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)]
    assert np.dot(boresight, icrs) == pytest.approx(1.0, abs=1e-12)
    # and it is the attitude the frame was rendered at, to the solve's accuracy: tens of
    # arcsec about the roll axis at most for 25 stars in 6 deg (the sigmas printed are ~1"
    # cross and ~35" roll); 120" holds it with room
    assert (rot.inv() * truth).magnitude() < 120 * ARCSEC
    s = d["sigma_arcsec"]
    assert set(s) == {"x", "y", "roll"}
    assert [s["x"], s["y"], s["roll"]] == pytest.approx(list(sol.sigma_arcsec), rel=1e-9)
    assert s["roll"] > s["x"]  # about the boresight a narrow field sees less: a larger sigma


def test_batch_lines_carry_the_same_fields(frame, validator, tmp_path, capsys):
    path, _ = frame
    d = tmp_path / "two"
    d.mkdir()
    (d / "a.png").symlink_to(path)
    (d / "b.png").write_bytes(b"not an image")
    assert main(["solve", str(d), "--fov-deg", "6", "--json"]) == 1  # b.png does not solve
    rows = {
        r["image"].rsplit("/", 1)[-1]: r
        for r in map(json.loads, capsys.readouterr().out.splitlines())
    }
    assert len(rows["a.png"]["quaternion_xyzw"]) == 4
    assert set(rows["a.png"]["sigma_arcsec"]) == {"x", "y", "roll"}
    assert rows["b.png"]["status"] == "unreadable"
    for row in rows.values():
        validator.validate(row)


def test_schema_is_printed_and_refuses_what_it_does_not_describe(validator, capsys):
    assert main(["solve", "--schema"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["title"] == "starsense solve"
    good = {"image": "f.png", "status": "no_match", "message": "", "time_ms": 1.0}
    validator.validate(good)
    for bad in (
        {**good, "sigma_arcsec": [1.0, 1.0, 3.0]},  # the labelled form only
        {**good, "quaternion_xyzw": [0.0, 0.0, 1.0]},  # four numbers
        {**good, "status": "fine"},
        {**good, "new_key": 1},  # a key the schema does not document
    ):
        assert not validator.is_valid(bad), bad


def test_no_attitude_gives_nulls():
    fields = attitude_fields(Solution("no_match", "nothing matched"))
    assert fields == {"quaternion_xyzw": None, "rotation_matrix": None, "sigma_arcsec": None}
