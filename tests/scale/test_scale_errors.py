"""Deep catalogues (starsense.scale): bad input gives a specific error, quickly, and the core
stays light.

Network is not needed: the unreachable cases use a closed loopback port (refused at once) and
an unroutable address (TEST-NET-1, RFC 5737) with a 1 s connect timeout.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

import starsense.scale
from starsense.catalog import load_catalog
from starsense.cli import main
from starsense.errors import InputError
from starsense.geometry.fov import CircularFov
from starsense.scale import (
    CatalogUnavailableError,
    MissingColumnsError,
    ScaleNotInstalledError,
    SchedulerUnreachableError,
)
from starsense.scale._deps import quiet_third_party_warnings, require


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_import_starsense_does_not_import_lsdb_or_dask():
    code = (
        "import sys, starsense, starsense.scale, starsense.cli, starsense.analysis.limits\n"
        "heavy = [m for m in sys.modules if m.split('.')[0] in "
        "('lsdb', 'hats', 'hats_import', 'dask', 'distributed', 'pandas')]\n"
        "print(heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_missing_extra_raises_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "lsdb", None)  # makes `import lsdb` raise ImportError
    with pytest.raises(ScaleNotInstalledError, match=r"starsense\[scale\]"):
        require("lsdb")
    assert issubclass(ScaleNotInstalledError, InputError)


def test_load_catalog_points_hats_to_the_scale_commands():
    with pytest.raises(InputError, match=r"limit sky.*availability static"):
        load_catalog("hats:/somewhere")


def test_dask_option_needs_a_hats_catalogue(capsys):
    code, _, err = run(capsys, "limit", "sky", "--dask", "tcp://127.0.0.1:1")
    assert code == 2 and "--dask runs hats: catalogues" in err


# -- everything below needs the extra -----------------------------------------------------------


@pytest.fixture(scope="module")
def scale():
    try:
        require("lsdb", "hats", "distributed")
    except ScaleNotInstalledError as exc:
        pytest.skip(f"starsense[scale] not installed: {exc}")

    return starsense.scale


def test_missing_local_catalogue(scale, tmp_path):
    with pytest.raises(CatalogUnavailableError, match="not found"):
        scale.open_hats(f"hats:{tmp_path / 'nothing'}")


def test_directory_that_is_not_hats(scale, tmp_path):
    (tmp_path / "stars.csv").write_text("ra,dec\n1,2\n")
    with pytest.raises(CatalogUnavailableError, match="not a readable HATS catalogue"):
        scale.open_hats(f"hats:{tmp_path}")
    with pytest.raises(CatalogUnavailableError, match="is a file"):
        scale.open_hats(f"hats:{tmp_path / 'stars.csv'}")


def test_refused_url_fails_at_once(scale, capsys):
    t0 = time.perf_counter()
    code, out, err = run(capsys, "limit", "sky", "--catalog", "hats:http://127.0.0.1:9/hats/x")
    assert code == 2 and out == ""
    assert err.startswith("error: cannot reach HATS catalogue http://127.0.0.1:9/hats/x")
    assert "connection refused" in err
    assert len(err.strip().splitlines()) == 1  # one line, no traceback
    assert time.perf_counter() - t0 < 2.0  # refused at once: no lsdb import, no cluster


def test_silent_server_times_out_saying_how_long(scale):
    # a server that accepts connections (the kernel does, from the listen backlog) but never
    # answers: the request times out after timeout_s and the message says how long it waited
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = server.getsockname()[1]
        t0 = time.perf_counter()
        with pytest.raises(CatalogUnavailableError, match=r"no answer after 1\.\d s"):
            scale.open_hats(f"hats:http://127.0.0.1:{port}/x", timeout_s=1.0)
    assert time.perf_counter() - t0 < 5.0  # one 1 s read timeout, not three


def test_refused_url_fails_at_once_in_the_library(scale):
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = server.getsockname()[1]  # a port just freed: nothing listens there
    t0 = time.perf_counter()
    with pytest.raises(CatalogUnavailableError, match="connection refused"):
        scale.open_hats(f"hats:http://127.0.0.1:{port}/x", timeout_s=5.0)
    assert time.perf_counter() - t0 < 2.0  # at once, not after the 5 s timeout


def test_unreachable_scheduler_fails_quickly(scale):
    t0 = time.perf_counter()
    with (
        pytest.raises(SchedulerUnreachableError, match=r"connection refused by 127\.0\.0\.1:1 "),
        scale.dask_client("tcp://127.0.0.1:1", timeout_s=5.0),
    ):
        pass  # pragma: no cover
    assert time.perf_counter() - t0 < 2.0  # refused at once, not after the 5 s timeout


@pytest.mark.parametrize(
    "address", ["local:0", "local:x", "tcp://", "http://host:1", "nohost", "tcp://127.0.0.1:99999"]
)
def test_bad_scheduler_address(scale, address):
    with pytest.raises(InputError, match="--dask"), scale.dask_client(address):
        pass  # pragma: no cover


@pytest.fixture(scope="module")
def g_only_hats(scale, tmp_path_factory):
    """A real HATS catalogue with positions and G but no colour (written by lsdb)."""
    import lsdb

    pd = pytest.importorskip("pandas")  # with lsdb (the scale extra), lazily like lsdb

    rng = np.random.default_rng(0)
    n = 300
    frame = pd.DataFrame(
        {
            "ra": rng.uniform(0, 360, n),
            "dec": np.degrees(np.arcsin(rng.uniform(-1, 1, n))),
            "phot_g_mean_mag": rng.uniform(2, 10, n),
        }
    )
    path = tmp_path_factory.mktemp("gonly") / "g_only"
    with warnings.catch_warnings():
        quiet_third_party_warnings()  # lsdb's own pandas-3.1 deprecations
        lsdb.from_dataframe(frame, catalog_name="g_only", margin_threshold=None).write_catalog(path)
    return scale.open_hats(f"hats:{path}")


def test_catalogue_without_colour_for_the_limit(scale, g_only_hats):
    t0 = time.perf_counter()
    with pytest.raises(MissingColumnsError, match="no column for a magnitude and colour"):
        scale.sky_limit(g_only_hats, client=object())  # refused before any cluster work
    with pytest.raises(MissingColumnsError, match="BP-RP"):
        scale.sky_limit(g_only_hats, colour="BP-RP", client=object())
    assert time.perf_counter() - t0 < 1.0


def test_catalogue_without_the_band_for_availability(scale, g_only_hats):
    with pytest.raises(MissingColumnsError, match="the V magnitude"):
        scale.static_availability(
            g_only_hats, CircularFov(0.1), max_mag=6.0, band="V", client=object()
        )
    plan, band = scale.availability.band_plan(g_only_hats, None)  # default: the first it has
    assert band == "G" and plan.columns == ["ra", "dec", "phot_g_mean_mag"]


def test_import_without_position_columns_leaves_nothing(scale, tmp_path, capsys):
    (tmp_path / "cat.csv").write_text("alpha,delta,V\n10,20,5\n")
    code, _, err = run(
        capsys, "catalog", "import", str(tmp_path / "cat.csv"), str(tmp_path / "out")
    )
    assert code == 2 and "position column(s) ra, dec missing" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cat.csv"]


def test_a_csv_whose_header_is_not_text_is_one_line(tmp_path):
    # a PNG named .csv: pyarrow read its header as UTF-8 and raised UnicodeDecodeError (a
    # traceback out of `catalog import --dask`, found by a fresh seed of the bad-input sweep)
    pytest.importorskip("pyarrow")
    from starsense.scale.importer import input_columns

    path = tmp_path / "in.csv"
    path.write_bytes(b"\x89ra,dec\n1.0,2.0\n")  # a header name that is not UTF-8
    with pytest.raises(CatalogUnavailableError, match=r"in\.csv.*not UTF-8"):
        input_columns(path, "csv")
