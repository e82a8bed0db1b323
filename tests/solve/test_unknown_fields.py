"""Frames of 3 to 60 deg solve with the field unknown.

Each frame is rendered by our renderer through a sensor built here: the ESA camera's 1024 x
768 detector with a 100-count bias (a real 16-bit camera's offset, so that the background is
not clipped at zero) behind a pinhole lens giving the field wanted. The sky is Gaia to G = 10
for the narrow fields (the stars a 3-5 deg camera sees, many fainter than Hipparcos is complete)
and Hipparcos for the others. ``Solver()`` is given nothing: it searches 5-30 deg, then 25-70
deg, then 2.8-6 deg (Gaia when installed; :mod:`starsense.identify.fields`).

Tolerances: a right solution puts the boresight within a fraction of a pixel (centroids of
bright stars to ~0.1 px, averaged over tens of stars); 2 pixels leaves room for the widest
fields' few, blended stars, while a wrong identification is off by degrees. The field found is
the fitted plate scale: 0.3 % (1.5 px over the 1024 px width).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from starsense.catalog import load_catalog
from starsense.geometry.attitude import angular_separation, attitude_from_radec_roll
from starsense.identify import identify_ranked
from starsense.identify.fields import deep_catalog_available, unknown_field_plan
from starsense.render.scene import render_frame
from starsense.sensor import load_sensor
from starsense.solve.pinhole import pinhole_vectors
from starsense.solve.solver import Solver

# (RA, Dec, roll) deg: Orion (dense, bright), near the north galactic pole (sparse)
POINTINGS = [(83.8, -5.4, 30.0), (192.9, 27.1, 200.0)]


def _sensor(fov_deg: float):
    base = load_sensor("esa_blackfly")
    width = base.detector.columns * base.detector.pixel_pitch_m
    focal = width / 2.0 / math.tan(math.radians(fov_deg) / 2.0)
    # a lens no faster than f/1 (short focal lengths cannot keep the base's 18 mm aperture:
    # f/0.33 at 60 deg is no lens), the exposure lengthened to keep the photons per star
    aperture = min(base.optics.aperture_m, focal)
    return base.with_(
        optics=dataclasses.replace(base.optics, focal_length_m=focal, aperture_m=aperture),
        detector=dataclasses.replace(base.detector, bias_counts=100.0),
        exposure_s=base.exposure_s * (base.optics.aperture_m / aperture) ** 2,
    )


@pytest.fixture(scope="module")
def solver():
    return Solver()


def _check(solver, fov_deg: float, catalog: str, band: str | None, max_mag: float) -> None:
    sensor = _sensor(fov_deg)
    cat = load_catalog(catalog)
    pixel_rad = math.radians(fov_deg) / sensor.detector.columns
    for i, (ra, dec, roll) in enumerate(POINTINGS):
        truth = attitude_from_radec_roll(*(math.radians(a) for a in (ra, dec, roll)))
        frame = render_frame(sensor, truth, cat, band=band, max_mag=max_mag, rng=i)
        sol = solver(frame.image)
        assert sol.solved, f"{fov_deg} deg at {ra}, {dec}: {sol.status}: {sol.message}"
        err = float(
            angular_separation(sol.rotation.inv().apply([0, 0, 1]), truth.inv().apply([0, 0, 1]))
        )
        assert err < 2.0 * pixel_rad, (fov_deg, ra, dec, err / pixel_rad)
        assert sol.fov_deg == pytest.approx(fov_deg, rel=3e-3)


@pytest.mark.parametrize("fov_deg", [8.0, 20.0])
def test_common_fields_solve_unknown(solver, fov_deg):
    _check(solver, fov_deg, "hipparcos", None, 8.0)


@pytest.mark.slow
@pytest.mark.parametrize("fov_deg", [40.0, 60.0])
def test_wide_fields_solve_unknown(solver, fov_deg):
    _check(solver, fov_deg, "hipparcos", None, 6.5)


@pytest.mark.slow
@pytest.mark.parametrize("fov_deg", [3.0, 5.0])
def test_narrow_fields_solve_unknown_with_gaia(solver, fov_deg):
    if not deep_catalog_available():
        pytest.skip("the narrow fields need the gaia extra (pip install 'starsense[gaia]')")
    _check(solver, fov_deg, "gaia", "G", 10.0)


def test_plan_uses_gaia_for_narrow_fields_only_when_installed():
    plan = unknown_field_plan("hipparcos")
    widths = [
        (round(math.degrees(f.min_fov_rad), 1), round(math.degrees(f.max_fov_rad), 1)) for f in plan
    ]
    assert widths == [(5.0, 30.0), (25.0, 70.0), (2.8, 6.0)]
    assert [f.catalog for f in plan[:2]] == ["hipparcos", "hipparcos"]
    assert plan[2].catalog == ("gaia" if deep_catalog_available() else "hipparcos")
    # a catalogue the user chose is used for every range, in its own band
    assert {(f.catalog, f.band) for f in unknown_field_plan("gaia")} == {("gaia", "G")}


@pytest.mark.slow  # searches every range, the narrow Gaia database included (~100 MB to load)
def test_no_wrong_answer_on_noise_or_a_mirrored_sky(solver):
    """Every range of the search is tried on these, and none may return an attitude.

    Random points are pure noise; a mirrored (parity-flipped) frame has the same edge ratios
    as the sky, so it reaches verification, where no proper rotation fits it.
    """
    rng = np.random.default_rng(13)
    plan = unknown_field_plan()
    for _ in range(5):
        xy = rng.uniform((0, 0), (1023, 767), size=(20, 2))
        v = pinhole_vectors(xy[:, 0], xy[:, 1], shape=(768, 1024), fov_rad=math.radians(15.0))
        for field_range in plan:
            ident = identify_ranked(
                solver.identifier(None, field_range),
                v,
                -np.arange(20.0),
                None,
                assumed_fov_rad=math.radians(15.0),
            )
            assert not ident.solved, (field_range, ident)
    sensor = _sensor(20.0)
    truth = attitude_from_radec_roll(*(math.radians(a) for a in POINTINGS[0]))
    frame = render_frame(sensor, truth, load_catalog("hipparcos"), max_mag=8.0, rng=3)
    assert solver(frame.image).solved  # the frame itself solves ...
    mirrored = solver(frame.image[:, ::-1])  # ... its mirror image does not: the parity check
    assert not mirrored.solved and mirrored.status == "mirrored", mirrored.status  # says so
