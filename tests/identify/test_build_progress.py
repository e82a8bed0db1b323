"""The line on stderr while an identification database builds (identify.progress)."""

from __future__ import annotations

import io
import math
import time

import numpy as np

from starsense.catalog.table import Catalog
from starsense.identify import build_database
from starsense.identify.progress import BuildProgress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_build_within_the_grace_time_says_nothing():
    out = io.StringIO()
    with BuildProgress("the database", after_s=3600.0, stream=out) as progress:
        progress.step("patterns")
    assert out.getvalue() == ""


def test_past_the_grace_time_a_log_gets_a_line_when_it_starts_and_one_when_done():
    out = io.StringIO()
    with BuildProgress("the 12 deg database", after_s=0.0, stream=out) as progress:
        progress.step("patterns")
    lines = out.getvalue().splitlines()
    assert lines == [
        "starsense: building the 12 deg database ...",
        lines[1],  # the total, whatever it was
    ]
    assert lines[1].startswith("starsense: building the 12 deg database: done in ")
    assert "\r" not in out.getvalue()  # a log is not redrawn


def test_on_a_terminal_the_line_is_redrawn_and_ends_with_the_total():
    out = _Terminal()
    # the drawing thread held back (an hour's grace): the line is drawn here, as it would be
    with BuildProgress("the 12 deg database", after_s=3600.0, stream=out) as progress:
        progress.step("hashing 5 patterns")
        progress._show()
        progress._draw()
    text = out.getvalue()
    assert text.startswith("\r\x1b[Kstarsense: building the 12 deg database: hashing 5 patterns")
    final = text.rsplit("\r\x1b[K", 1)[1]
    assert final.startswith("starsense: building the 12 deg database: done in ")
    assert final.endswith(" s\n") and text.count("\n") == 1


def test_a_build_that_fails_says_it_stopped():
    out = io.StringIO()
    try:
        with BuildProgress("the database", after_s=0.0, stream=out):
            raise MemoryError
    except MemoryError:
        pass
    assert "the database: stopped in " in out.getvalue()


def test_the_terminal_line_fits_its_width():
    progress = BuildProgress("the 12 deg identification database (once; cached in /x/y/z)")
    progress.step("hashing 2,195,803 patterns")
    progress._t0 = time.perf_counter()  # started now: "0 s"
    line = progress._line(60)
    assert len(line) <= 60 and line.endswith(" s") and "hashing 2,195,803 patterns" in line


def test_building_a_database_names_its_steps(tmp_path, capsys, monkeypatch):
    # a small catalogue builds in well under a second: with the grace time set to zero the
    # cached build still says what it builds and where it caches it
    monkeypatch.setattr("starsense.identify.progress.SHOW_AFTER_S", 0.0)
    rng = np.random.default_rng(0)
    v = rng.normal(size=(3000, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    cat = Catalog.from_columns(
        name="random",
        source="test",
        epoch_yr=2000.0,
        ids=np.arange(3000),
        ra_deg=np.degrees(np.arctan2(v[:, 1], v[:, 0]) % (2 * np.pi)),
        dec_deg=np.degrees(np.arcsin(v[:, 2])),
        mags={"V": rng.uniform(0, 6, 3000)},
    )
    build_database(cat, math.radians(20.0), cache_dir=tmp_path)
    err = capsys.readouterr().err
    assert "starsense: building the 20 deg identification database (once; cached in" in err
    assert str(tmp_path) in err and ": done in " in err
