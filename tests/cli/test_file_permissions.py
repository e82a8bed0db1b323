"""Files written by the tool get the same permissions whichever command wrote them.

Every file a command writes for the user is ``0o666 & ~umask`` (what any program creating a file
would give), every folder it creates ``0o777 & ~umask``: not ``mkstemp``'s 0600, and not a fixed
0644 that ignores a stricter umask. Each command runs in-process through ``starsense.cli.main``,
under a umask of 0o022 and of 0o077.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from starsense.cli import main
from starsense.report.section import ReportContext


@pytest.fixture(params=[0o022, 0o077], ids=["umask022", "umask077"])
def umask(request):
    old = os.umask(request.param)
    try:
        yield request.param
    finally:
        os.umask(old)


def _run(capsys, *argv) -> None:
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    assert code == 0, out.err


def _assert_modes(paths: list[Path], umask: int) -> None:
    assert paths, "nothing was written"
    wrong = {}
    for p in paths:
        mode = p.stat().st_mode & 0o777
        want = (0o777 if p.is_dir() else 0o666) & ~umask
        if mode != want:
            wrong[p.name] = f"{mode:o} (want {want:o})"
    assert not wrong, wrong


def _written(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*"))


def test_render_frame_and_truth(tmp_path, capsys, umask):
    _run(capsys, "render", "--sensor", "st16", "--max-mag", "2", "--out", tmp_path / "f.png")
    files = _written(tmp_path)
    assert [p.name for p in files] == ["f.png", "f.png.json"]
    _assert_modes(files, umask)


def test_solve_wcs(tmp_path, capsys, umask, shared_dir):
    folder = shared_dir / "data" / "images" / "esa"
    name = next(iter(json.loads((folder / "reference.json").read_text())["frames"]))
    out = tmp_path / "sol.wcs.fits"
    _run(capsys, "solve", folder / name, "--sensor", "esa_blackfly", "--wcs", out)
    files = _written(tmp_path)
    assert [p.name for p in files] == ["sol.wcs.fits"]
    _assert_modes(files, umask)


def test_slew_tolerance_plot(tmp_path, capsys, umask):
    _run(
        capsys,
        "slew",
        "tolerance",
        "--magnitudes",
        "3",
        "--rates-deg-s",
        "0,1",
        "--trials",
        "2",
        "--plot",
        tmp_path / "slew.png",
    )
    files = _written(tmp_path)
    assert [p.name for p in files] == ["slew.png"]
    _assert_modes(files, umask)


def test_limit_curve_plot(tmp_path, capsys, umask):
    _run(capsys, "limit", "curve", "--plot", tmp_path / "curve.png")
    files = _written(tmp_path)
    assert [p.name for p in files] == ["curve.png"]
    _assert_modes(files, umask)


def test_availability_static_plot_and_maps(tmp_path, capsys, umask):
    _run(
        capsys,
        "availability",
        "static",
        "--n-orientations",
        "200",
        "--plot",
        tmp_path / "static.png",
        "--maps",
        tmp_path / "maps",
    )
    files = _written(tmp_path)
    assert {p.name for p in files} >= {"static.png", "maps", "static_sparse.png"}
    _assert_modes(files, umask)


def test_report_figure_writer(tmp_path, umask):
    # the writer every report section uses, without building the whole report (see the slow
    # test below for the command itself)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ctx = ReportContext(
        work_dir=tmp_path,
        catalog_name="test",
        n_catalog=0,
        stars={},
        diameter_m=0.1,
        exposure_s=0.01,
    )
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    try:
        ctx.save_figure(fig, "figure.png")
    finally:
        plt.close(fig)
    files = _written(tmp_path)
    assert [p.name for p in files] == ["figure.png"]
    _assert_modes(files, umask)


@pytest.mark.slow
def test_report_out(tmp_path, capsys, umask):
    # ~1 min: every section of the report, with the fewest slew trials
    _run(capsys, "report", "--out", tmp_path / "report", "--slew-trials", "2", "--trials", "2")
    files = _written(tmp_path)
    assert {"report", "index.html", "report.json"} <= {p.name for p in files}
    _assert_modes(files, umask)
