"""The slew section's validation part: the ST-16's PSF width and QE against the paper."""

from __future__ import annotations

import json
import re
import time

import pytest

from starsense.report.section import ReportContext
from starsense.report.slew import slew_section
from starsense.report.slew_study import REPORT_SIGMAS_PX
from starsense.sensor import load_sensor

pytest.importorskip("starsense.detect.stack")


def test_slew_section_carries_the_psf_qe_study(tmp_path):
    ctx = ReportContext(
        work_dir=tmp_path,
        catalog_name="none",
        n_catalog=0,
        stars={},
        diameter_m=0.012,
        exposure_s=0.1,
        seed=0,
        slew_trials=2,
        sensor=load_sensor("st16"),
    )
    t0 = time.perf_counter()
    section = slew_section(ctx)
    elapsed = time.perf_counter() - t0
    assert "slew_study_psf_qe.png" in section.figures
    for name in section.figures:
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"
    data = section.data["psf_qe_study"]
    json.dumps(section.data, allow_nan=False)  # report.json has no NaN
    assert data["sigmas_px"] == list(REPORT_SIGMAS_PX)
    # the conclusion, on the coarse grid too: no sensible pair within the tolerance, and the
    # text names the shape (how the curve falls between the paper's rates)
    assert not data["best"]["reproduces"]
    html = section.html
    assert "no physically sensible pair reproduces the paper at every rate" in html
    assert re.search(r"from 1.5 to 2 deg/s the paper's m<sub>t</sub> falls by 0.5\d mag", html)
    assert "1.5 (preset)" in html
    # the summary speaks of the report's sensor; the paper's check stays in the section
    assert all(label.startswith("st16 ") for label, _ in section.summary)
    assert all("paper" not in label for label, _ in section.summary)
    # the study's budget: a few seconds of CPU; generous here for 2 shared cores
    assert elapsed < 60, elapsed
