"""Every analysis follows the sensor given: a sensor that is not a preset gets its own limiting
magnitude, field and threshold curve in ``availability static|mission`` and in the report, the
numbers its datasheet gives."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from starsense.analysis.datasheet import datasheet
from starsense.analysis.sensor_detection import sensor_detection
from starsense.catalog import load_catalog
from starsense.cli.app import main
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.sensor import load_sensor

#: an IMX296-class camera (3.45 um, 1440 x 1080) behind a 25 mm f/1.4 lens, 50 ms; detection at
#: 5 sigma of its read noise (2.2 e- x 1 count/e- -> 11 counts)
IMX296 = """name = "imx296_25mm"
exposure_s = 0.05
[optics]
focal_length_m = 0.025
aperture_m = 0.017857
transmission = 0.9
[detector]
columns = 1440
rows = 1080
pixel_pitch_m = 3.45e-6
bit_depth = 12
gain_counts_per_e = 1.0
read_noise_e = 2.2
psf_sigma_px = 1.0
qe_mean = 0.6
passband_nm = [400.0, 900.0]
full_well_e = 10000.0
dark_current_e_s = 0.0
bias_counts = 0.0
[detection]
lit_pixel_counts = 11.0
min_pixels = 3
min_integrated_counts = 60.0
connectivity = 8
"""
SEED, N_ORIENT = 3, 300


@pytest.fixture(scope="module")
def imx(tmp_path_factory):
    path = tmp_path_factory.mktemp("imx") / "imx296.toml"
    path.write_text(IMX296)
    return path


@pytest.fixture(scope="module")
def sheet(imx):
    return datasheet(str(imx), n_trials=1, n_orientations=N_ORIENT, rng=SEED)


def run_json(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    assert code == 0, out.err
    return json.loads(out.out)


def _static_mag(sheet, imx) -> float:
    """The datasheet's threshold at rest: min(m_t(0), limit) of its own slew run."""
    det = sensor_detection(load_sensor(str(imx)), rng=SEED)
    assert det.limit_mag == sheet.limiting_magnitude  # the same run, bit for bit
    return det.static_mag


def test_static_availability_defaults_to_the_sensors_own(sheet, imx, capsys):
    d = run_json(
        capsys,
        "availability",
        "static",
        "--sensor",
        str(imx),
        "--fov",
        "rectangular",
        "--n-orientations",
        str(N_ORIENT),
        "--seed",
        str(SEED),
        "--json",
    )
    # the datasheet's limit is far past the ST-16's 5.75 this default used to be
    assert sheet.limiting_magnitude > 7.0
    assert d["max_mag"] == pytest.approx(_static_mag(sheet, imx), abs=1e-12)
    # the same boresights, rolls, stars and threshold: the same fraction, exactly
    assert d["availability"] == sheet.availability.lost_in_space


def _count_in_field(vectors, mags, limit, ra, dec, roll, half_fov):
    """Stars <= limit inside the rectangular field (pinhole: |x/z|, |y/z| <= tan(half))."""
    m = attitude_from_radec_roll(ra, dec, roll).as_matrix()
    v = vectors[mags <= limit] @ m.T
    z = v[:, 2]
    ok = (z > 0) & (np.abs(v[:, 0]) <= math.tan(half_fov[0]) * z)
    ok &= np.abs(v[:, 1]) <= math.tan(half_fov[1]) * z
    return int(ok.sum())


def test_mission_inertial_availability_equals_the_datasheets(sheet, imx, capsys):
    sens = load_sensor(str(imx))
    static = _static_mag(sheet, imx)
    cat = load_catalog("hipparcos")
    keep = np.isfinite(cat.mags["V"])
    vectors, mags = cat.vectors[keep], cat.mags["V"][keep]
    rng = np.random.default_rng(0)
    # a boresight far from the Sun (RA 0 at the March equinox) and the Earth (GEO at RA 0, the
    # Earth at RA 180, Dec 0), where the old default (V <= 5.75, circular) and the sensor's own
    # threshold disagree: fewer than 3 stars at 5.75, at least 3 at the sensor's threshold
    for _ in range(2000):
        ra, dec, roll = rng.uniform(1.2, 1.9), rng.uniform(0.9, 1.3), rng.uniform(0, 2 * np.pi)
        n_own = _count_in_field(vectors, mags, static, ra, dec, roll, sens.half_fov_rad)
        n_old = _count_in_field(vectors, mags, 5.75, ra, dec, roll, sens.half_fov_rad)
        if n_old < 3 <= n_own:
            break
    else:
        pytest.fail("no discriminating boresight found")
    d = run_json(
        capsys,
        "availability",
        "mission",
        "--orbit",
        "kepler:42164,0,0,0,0,0",
        "--attitude",
        f"inertial:{math.degrees(ra)},{math.degrees(dec)},{math.degrees(roll)}",
        "--heads",
        str(imx),
        "--start",
        "2025-03-20T12:00:00",
        "--duration-h",
        "0.05",
        "--step-s",
        "60",
        "--seed",
        str(SEED),
        "--json",
    )
    head = d["heads"][0]
    assert head["blinded_s"] == {"sun": 0, "moon": 0, "earth": 0}
    assert d["max_mag"] == pytest.approx(static, abs=1e-12)
    # no bright body, no rate: the stars the datasheet's threshold puts in this field, at every
    # step, and so lost in space at every step
    assert head["mean_stars"] == n_own
    assert head["lost_in_space_fraction"] == 1.0


@pytest.mark.slow
def test_report_availability_equals_the_datasheets(imx, tmp_path, monkeypatch):
    import starsense.report.availability as report_av
    import starsense.report.availability_track as report_track
    from starsense.photometry.stars import BlackBodyStars
    from starsense.report.datasheet import datasheet_section
    from starsense.report.section import ReportContext

    # the paper's parts (tracks, rendered frames) have their own tests: keep them short here
    monkeypatch.setattr(report_track, "FIDELITY_RATES_DEG_S", ())
    monkeypatch.setattr(report_track, "TRACK_RATES_DEG_S", (1.0,))
    monkeypatch.setattr(report_track, "TRACK_NODES_DEG", (0.0,))
    monkeypatch.setattr(report_av, "DYNAMIC_RATES_DEG_S", np.array([0.0, 1.0]))
    cat = load_catalog("hipparcos")
    ctx = ReportContext(
        work_dir=tmp_path,
        catalog_name=cat.name,
        n_catalog=len(cat),
        stars={"B-V": BlackBodyStars.from_catalog(cat)},
        diameter_m=0.017857,
        exposure_s=0.05,
        seed=SEED,
        sensor=load_sensor(str(imx)),
        datasheet_trials=1,
        catalog=cat,
    )
    sheet = datasheet_section(ctx).data["datasheet"]
    section = report_av.availability_section(ctx)
    own = section.data["sensor"]
    av = sheet["availability"]
    # the same analysis (field, boresights, rolls, stars, threshold curve): equal, not close
    assert own["rates_deg_s"] == pytest.approx(av["rates_deg_s"], abs=1e-12)
    assert own["lost_in_space"] == av["lost_in_space_at_rate"]
    assert own["tracking"] == av["tracking_at_rate"]
    assert own["limiting_magnitude"] == sheet["limiting_magnitude"]
    # and the summary quotes them, for this sensor (not the paper's m_t = 5.75)
    label, value = section.summary[0]
    assert label.startswith("imx296_25mm static availability")
    assert f"{100 * av['lost_in_space']:.2f}" in value
