"""Work bounded before it is allocated: every count has a cap, checked at the front door.

A count above its cap is refused with one line naming the option (or argument), the value and
the cap, before any catalogue is loaded or array allocated: each case here finishes in well
under a second, under the 4 GB memory guard of conftest.py (the old code asked for tens of GB
or ran for days).
"""

from __future__ import annotations

import time

import pytest

import starsense
from starsense.analysis.availability import AvailabilityAnalysis
from starsense.analysis.availability.pointings import (
    MAX_ORIENTATIONS,
    sky_attitudes,
    track_family_attitudes,
)
from starsense.analysis.centroid_trials import centroid_trials
from starsense.analysis.datasheet import DatasheetSettings
from starsense.analysis.guide_stars.fields import MAX_FIELD_TRIALS
from starsense.analysis.guide_stars.table1 import MAX_TABLE1_TRIALS, simulate_table1
from starsense.analysis.inputs import MAX_FRAMES
from starsense.analysis.limits.photons import MAX_PHOTON_TRIALS
from starsense.analysis.slew import MAX_SLEW_SAMPLES, MAX_TRIALS_PER_POINT
from starsense.analysis.trade import (
    MAX_DESIGNS_IN_PROCESS,
    MAX_DESIGNS_ON_CLUSTER,
    base_document,
    designs,
    parse_vary,
    run_trade,
)
from starsense.cli import main
from starsense.errors import InputError
from starsense.geometry.fov import CircularFov

BIG = 10**12

# fmt: off
CLI_CASES = [
    (["availability", "static", "--n-orientations", str(10**9)],
     ["--n-orientations", "1,000,000,000", f"{MAX_ORIENTATIONS:,}"]),
    (["availability", "dynamic", "--n-orientations", str(10**9)],
     ["--n-orientations", "1,000,000,000", f"{MAX_ORIENTATIONS:,}"]),
    (["availability", "track", "--track-samples", str(10**9)],
     ["--track-samples", "1,000,000,000", f"{MAX_ORIENTATIONS:,}"]),
    # each track is within the cap, all 181 together are not
    (["availability", "track", "--track-samples", "10000"],
     ["--track-samples", "10,000", "181 tracks", f"{MAX_ORIENTATIONS:,}"]),
    (["availability", "track", "--trials", str(BIG)], ["--trials", f"{MAX_TRIALS_PER_POINT:,}"]),
    (["availability", "fidelity", "--frames", str(BIG)], ["--frames", f"{MAX_FRAMES:,}"]),
    (["datasheet", "--trials", str(BIG)], ["--trials", f"{BIG:,}", f"{MAX_FRAMES:,}"]),
    (["datasheet", "--n-orientations", str(10**9)], ["--n-orientations", f"{MAX_ORIENTATIONS:,}"]),
    (["montecarlo", "--trials", str(BIG)], ["--trials", f"{BIG:,}", f"{MAX_FRAMES:,}"]),
    (["slew", "tolerance", "--trials", str(BIG)], ["--trials", f"{MAX_TRIALS_PER_POINT:,}"]),
    (["slew", "study", "--trials", str(BIG)], ["--trials", f"{MAX_TRIALS_PER_POINT:,}"]),
    (["availability", "mission", "--heads", "st16", "--trials", str(BIG)],
     ["--trials", f"{MAX_TRIALS_PER_POINT:,}"]),
    (["report", "--trials", str(BIG), "--out", "{out}/r"], ["--trials", f"{MAX_FRAMES:,}"]),
    (["report", "--slew-trials", str(BIG), "--out", "{out}/r"],
     ["--slew-trials", f"{MAX_TRIALS_PER_POINT:,}"]),
    (["guide-stars", "simulate", "--trials", str(BIG)], ["--trials", f"{MAX_TABLE1_TRIALS:,}"]),
    (["guide-stars", "field", "--trials", str(BIG)], ["--trials", f"{MAX_FIELD_TRIALS:,}"]),
    (["limit", "photons", "--trials", str(BIG)], ["--trials", f"{MAX_PHOTON_TRIALS:,}"]),
    (["trade", "--vary", "exposure_s=0.01,0.1", "--workers", "1000"], ["--workers", "64"]),
    (["trade", "--vary", "exposure_s=0.01:0.1:1000000000"],
     ["exposure_s", "1,000,000,000 values", f"{MAX_DESIGNS_ON_CLUSTER:,}"]),
    (["trade", "--vary", "exposure_s=0.01:0.1:1000", "--vary", "optics.aperture_m=0.01:0.02:20"],
     ["20,000 designs", f"{MAX_DESIGNS_IN_PROCESS:,}", "--dask"]),
    # a cluster lifts the in-process cap, not the grid's: refused before any cluster starts
    (["trade", "--vary", "exposure_s=0.01:0.1:1000", "--vary", "optics.aperture_m=0.01:0.02:1000",
      "--dask", "local:1"], ["1,000,000 designs", f"{MAX_DESIGNS_ON_CLUSTER:,}"]),
    (["trade", "--vary", "exposure_s=0.01,0.1", "--frames", str(BIG)],
     ["--frames", f"{MAX_FRAMES:,}"]),
]
# fmt: on


@pytest.mark.parametrize(("argv", "fragments"), CLI_CASES, ids=lambda x: " ".join(x)[:60])
def test_count_above_its_cap_is_one_line_exit_2(argv, fragments, tmp_path, capsys):
    start = time.perf_counter()
    code = main([a.replace("{out}", str(tmp_path)) for a in argv])
    captured = capsys.readouterr()
    assert code == 2, captured
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    # refused at the front door: no catalogue load, no Monte Carlo (a few seconds at most on
    # a loaded 2-core machine; the cases that are accepted take minutes or run out of memory)
    assert time.perf_counter() - start < 20.0
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("call", "fragments"),
    [
        (lambda: starsense.slew_tolerance("st16", n_trials=BIG), ["n_trials", "100,000"]),
        (lambda: starsense.slew_tolerance("st16", n_trials=float("nan")), ["n_trials", "nan"]),
        # every count within its cap, their product (magnitudes x rates x trials) not
        (
            lambda: starsense.slew_tolerance(
                "st16", n_trials=90_000, magnitudes=[float(m) for m in range(40)]
            ),
            ["n_trials = 90,000", "40 magnitudes x 40 rates", f"{MAX_SLEW_SAMPLES:,}"],
        ),
        (lambda: starsense.montecarlo("st16", n_trials=BIG), ["n_trials", f"{MAX_FRAMES:,}"]),
        (lambda: starsense.montecarlo("st16", n_trials=float("nan")), ["n_trials", "nan"]),
        (lambda: starsense.datasheet("st16", n_trials=BIG), ["n_trials", f"{MAX_FRAMES:,}"]),
        (lambda: starsense.datasheet("st16", n_orientations=10**9), ["n_orientations"]),
        (lambda: starsense.datasheet("st16", n_slew_trials=BIG), ["n_slew_trials"]),
        (lambda: starsense.datasheet("st16", n_rate_trials=BIG), ["n_rate_trials"]),
        (lambda: DatasheetSettings(n_trials=float("nan")), ["n_trials", "nan"]),
        (lambda: sky_attitudes(10**9), ["n_orientations", f"{MAX_ORIENTATIONS:,}"]),
        (lambda: track_family_attitudes([0.0, 0.5], 600_000), ["1,200,000 orientations"]),
        (
            lambda: AvailabilityAnalysis(
                [[0.0, 0.0, 1.0]], [1.0], CircularFov(0.1), n_orientations=10**9
            ),
            ["n_orientations"],
        ),
        (lambda: simulate_table1(n_trials=BIG), ["n_trials", f"{MAX_TABLE1_TRIALS:,}"]),
        (lambda: centroid_trials("st16", n_trials=BIG), ["n_trials", "1,000,000"]),
        (
            lambda: designs(
                base_document("st16"),
                [parse_vary("exposure_s=0.01:0.1:1000"), parse_vary("optics.aperture_m=1:2:1000")],
            ),
            ["1,000,000 designs"],
        ),
        (
            lambda: run_trade(
                designs(
                    base_document("st16"),
                    [parse_vary("exposure_s=0.01:0.1:200"), parse_vary("optics.aperture_m=1:2:60")],
                )
            ),
            ["12,000 designs", "without a Dask client"],
        ),
    ],
)
def test_api_count_above_its_cap_is_an_input_error(call, fragments):
    start = time.perf_counter()
    with pytest.raises(InputError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert time.perf_counter() - start < 20.0


@pytest.mark.parametrize(
    "shape", [(1, 100_000), (100_000, 1), (3, 60_000), (1, 1), (2, 2), (40, 4_000), (100, 31)]
)
def test_a_strip_of_a_frame_is_one_line_in_bounded_memory(shape, tmp_path, capsys):
    # a frame thinner than the detector's noise boxes (a 1 x 100,000 PNG took 6.1 GB once,
    # then a reshape error): one line, quickly, under the 4 GB guard of conftest.py
    import numpy as np
    from PIL import Image

    path = tmp_path / f"strip_{shape[0]}x{shape[1]}.png"
    noise = np.random.default_rng(50).integers(0, 200, shape).astype(np.uint8)
    Image.fromarray(noise).save(path)
    t0 = time.perf_counter()
    code = main(["solve", str(path)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert path.name in err and "no star" in err, err  # noise only: nothing to solve
    assert time.perf_counter() - t0 < 30.0
