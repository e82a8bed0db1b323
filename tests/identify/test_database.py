"""The identification database: pattern descriptors, thinning, build and on-disk cache."""

from __future__ import annotations

import json
import logging
import math
import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense._io import dir_mode, file_mode
from starsense.errors import InputError
from starsense.identify import build_database, edge_ratios, pattern_edges, thin_by_region
from starsense.identify import cache as cache_module
from starsense.identify import database as database_module
from starsense.identify.cache import IN_MEMORY_MAX_BYTES, database_cache_file


def _random_pattern(rng, spread_rad=0.05):
    offsets = rng.normal(0.0, spread_rad, (4, 2))
    v = np.column_stack([offsets, np.ones(4)])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_ratios_invariant_under_rotation_and_order():
    rng = np.random.default_rng(3)
    v = _random_pattern(rng)
    ratios, largest = edge_ratios(pattern_edges(v[None]))
    rotated = Rotation.random(random_state=rng).apply(v)
    r2, l2 = edge_ratios(pattern_edges(rotated[None]))
    np.testing.assert_allclose(r2, ratios, atol=1e-12)
    np.testing.assert_allclose(l2, largest, rtol=1e-12)
    r3, _ = edge_ratios(pattern_edges(v[[2, 0, 3, 1]][None]))
    np.testing.assert_allclose(r3, ratios, atol=1e-12)
    assert ratios.shape == (1, 5)
    assert np.all((ratios > 0) & (ratios <= 1)) and np.all(np.diff(ratios) >= 0)


def test_ratios_invariant_under_scale():
    # Scaling the angles scales every edge; the ratios do not change. For the angles of a
    # pinhole camera whose focal length is wrong by 10 % the change stays far below the
    # default pattern_max_error of 0.005 in a 15 deg field.
    rng = np.random.default_rng(4)
    edges = pattern_edges(_random_pattern(rng)[None])
    np.testing.assert_allclose(edge_ratios(1.7 * edges)[0], edge_ratios(edges)[0], atol=1e-15)
    v = _random_pattern(rng, spread_rad=0.08)
    t = v[:, :2] / v[:, 2:3] * 1.1
    w = np.column_stack([t, np.ones(4)])
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    diff = np.abs(edge_ratios(pattern_edges(w[None]))[0] - edge_ratios(pattern_edges(v[None]))[0])
    assert diff.max() < 0.005


def test_thin_by_region_keeps_the_brightest(hipparcos):
    mags = np.asarray(hipparcos.mags["V"])
    keep = thin_by_region(hipparcos.vectors, mags, radius_rad=math.radians(5), n_per_region=10)
    assert 0 < keep.sum() < 0.2 * len(mags)
    # The 100 brightest stars of the sky are each among the 10 brightest of their region.
    finite = np.flatnonzero(np.isfinite(mags))
    brightest = finite[np.argsort(mags[finite])[:100]]
    assert keep[brightest].all()
    assert not keep[~np.isfinite(mags)].any()


def test_build_is_fast_and_sized(db15):
    # ~5 s on an idle 2-core machine (1.6 M patterns, 13 pattern stars per field); the limit
    # leaves room for a loaded machine (the build runs once, then the disk cache serves it).
    assert db15.build_time_s < 20.0
    assert 1000 < db15.is_pattern_star.sum() <= len(db15)
    assert db15.patterns.shape[1] == 4 and len(db15.patterns) > 10_000
    assert np.all(np.diff(db15.pattern_keys) >= 0)
    assert np.all(np.diff(db15.pair_angles_rad) >= 0)
    assert db15.pair_angles_rad.max() <= 1.3 * db15.params.max_fov_rad + 1e-12
    assert np.all(np.diff(db15.mags) >= 0)  # brightest first
    assert db15.patterns.max() < len(db15)


def test_cache_round_trip(hipparcos, tmp_path, monkeypatch):
    fov = math.radians(20)
    db = build_database(hipparcos, fov, cache_dir=tmp_path)
    path, _ = database_cache_file(hipparcos, db.params, tmp_path)
    assert path.is_dir()
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left (_io)
    for entry in path.iterdir():
        assert entry.stat().st_mode & 0o777 == file_mode()  # 0666 less the umask, not 0600
    assert path.stat().st_mode & 0o777 == dir_mode()

    def no_build(*args, **kwargs):
        raise AssertionError("rebuilt although cached")

    monkeypatch.setattr(database_module, "_build", no_build)
    again = build_database(hipparcos, fov, cache_dir=tmp_path)
    for name in db._ARRAYS:
        array = getattr(again, name)
        np.testing.assert_array_equal(array, getattr(db, name))
        if array.nbytes > IN_MEMORY_MAX_BYTES:
            # a pattern table, memory-mapped read-only: opening it does not read it
            assert isinstance(array.base, np.memmap)
            assert not array.flags.writeable
        else:  # a star table, in memory and writable like any array a user gets
            assert array.flags.writeable
    assert any(getattr(again, n).nbytes > IN_MEMORY_MAX_BYTES for n in db._ARRAYS)
    # what scipy refuses on a read-only buffer works on the star table
    Rotation.identity().apply(again.vectors)
    assert again.params == db.params
    # other parameters -> another key -> a rebuild
    with pytest.raises(AssertionError, match="rebuilt"):
        build_database(hipparcos, fov, cache_dir=tmp_path, pattern_stars_per_fov=9)


@pytest.mark.slow
def test_cache_ignores_corrupt_file(hipparcos, tmp_path):
    fov = math.radians(25)
    db = build_database(hipparcos, fov, cache=False)
    path, _ = database_cache_file(hipparcos, db.params, tmp_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"not a database directory")
    again = build_database(hipparcos, fov, cache_dir=tmp_path)
    np.testing.assert_array_equal(again.patterns, db.patterns)
    # a truncated array in a cached directory: rebuilt and replaced, not used
    with open(path / "patterns.npy", "r+b") as f:
        f.truncate(200)
    third = build_database(hipparcos, fov, cache_dir=tmp_path)
    np.testing.assert_array_equal(third.patterns, db.patterns)
    assert (path / "patterns.npy").stat().st_size == 128 + db.patterns.nbytes  # header + data


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"max_fov_rad": float("nan")}, "max_fov_rad"),
        ({"max_fov_rad": math.radians(200)}, "max_fov_rad"),
        ({"max_fov_rad": 0.1, "min_fov_rad": 0.2}, "must not exceed"),
        ({"max_fov_rad": 0.1, "pattern_stars_per_fov": 3}, "pattern_stars_per_fov"),
        ({"max_fov_rad": 0.1, "band": "K"}, "no 'K' magnitudes"),
    ],
)
def test_bad_parameters(hipparcos, kwargs, match):
    with pytest.raises(InputError, match=match):
        build_database(hipparcos, cache=False, **kwargs)


def _garble(path, offset_from_end: int = 4096) -> None:
    """Overwrite 64 bytes inside a file's data in place (its size unchanged), as a disk error."""
    size = path.stat().st_size
    with open(path, "r+b") as f:
        f.seek(max(128, size - offset_from_end))
        chunk = bytearray(f.read(64))
        f.seek(max(128, size - offset_from_end))
        f.write(bytes(b ^ 0xFF for b in chunk))


@pytest.mark.parametrize("name", ["patterns", "pattern_keys", "vectors", "ids", "pairs"])
def test_cache_detects_a_garbled_file_rebuilds_and_says_so(
    name, hipparcos, tmp_path, monkeypatch, caplog
):
    fov = math.radians(25)
    db = build_database(hipparcos, fov, cache_dir=tmp_path)
    path, _ = database_cache_file(hipparcos, db.params, tmp_path)
    before = os.stat(path / f"{name}.npy")
    _garble(path / f"{name}.npy")
    # the times put back as they were: the change of the file's ctime and content still shows
    os.utime(path / f"{name}.npy", ns=(before.st_atime_ns, before.st_mtime_ns))
    builds = []
    real_build = database_module._build
    monkeypatch.setattr(
        database_module, "_build", lambda *a, **k: builds.append(1) or real_build(*a, **k)
    )
    with caplog.at_level(logging.WARNING, logger="starsense.identify.cache"):
        again = build_database(hipparcos, fov, cache_dir=tmp_path)
    assert builds == [1]  # rebuilt, not used
    said = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert any(f"{name}.npy does not match its checksum" in m and "rebuilding" in m for m in said)
    for array in db._ARRAYS:
        np.testing.assert_array_equal(getattr(again, array), getattr(db, array))
    # the rebuilt copy replaced the garbled one and opens without a rebuild or a warning
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="starsense.identify.cache"):
        third = build_database(hipparcos, fov, cache_dir=tmp_path)
    assert builds == [1] and not caplog.records
    np.testing.assert_array_equal(getattr(third, name), getattr(db, name))


def test_cache_hashes_a_file_once_per_version_of_it(hipparcos, tmp_path, monkeypatch):
    """An unchanged database is not hashed again on open (300 MB take ~0.5 s to hash)."""
    fov = math.radians(25)
    build_database(hipparcos, fov, cache_dir=tmp_path)
    hashed = []
    real = cache_module._file_checksum
    monkeypatch.setattr(cache_module, "_file_checksum", lambda p: hashed.append(p.name) or real(p))
    build_database(hipparcos, fov, cache_dir=tmp_path)
    assert hashed == []  # verified when written
    path = next(tmp_path.iterdir())
    (path / "verified.json").unlink()  # e.g. a copy without it: every file hashed once, then not
    build_database(hipparcos, fov, cache_dir=tmp_path)
    assert sorted(hashed) == sorted(
        f"{a}.npy" for a in database_module.IdentificationDatabase._ARRAYS
    )
    hashed.clear()
    build_database(hipparcos, fov, cache_dir=tmp_path)
    assert hashed == []


def test_cache_of_an_older_format_is_rebuilt(hipparcos, tmp_path, monkeypatch):
    fov = math.radians(25)
    db = build_database(hipparcos, fov, cache_dir=tmp_path)
    path, _ = database_cache_file(hipparcos, db.params, tmp_path)
    meta = json.loads((path / "meta.json").read_text())
    (path / "meta.json").write_text(json.dumps({**meta, "format": 2}))
    assert database_module.IdentificationDatabase.load(path) is None
    del meta["files"]  # the current format without its checksums: refused, not trusted
    (path / "meta.json").write_text(json.dumps(meta))
    assert database_module.IdentificationDatabase.load(path) is None


def _rss_file_bytes() -> int | None:
    """This process's resident pages of mapped files (Linux's RssFile), bytes; None elsewhere."""
    try:
        with open("/proc/self/status") as fh:
            status = fh.read()
    except OSError:
        return None
    for line in status.splitlines():
        if line.startswith("RssFile:"):
            return int(line.split()[1]) * 1024
    return None


def test_page_in_reads_the_mapped_tables(hipparcos, tmp_path):
    """A database opened from the cache maps its pattern tables; page_in makes them resident.

    Opening maps the files without reading them (a lookup then reads a page at a time); after
    page_in the process holds every page of the mapped tables: its resident file pages grow by
    their size (a 1 % slack for pages the kernel dropped meanwhile), the values unchanged.
    """
    fov = math.radians(20)
    built = build_database(hipparcos, fov, cache_dir=tmp_path)
    db = build_database(hipparcos, fov, cache_dir=tmp_path)  # from the cache: freshly mapped
    mapped = [n for n in db._ARRAYS if isinstance(getattr(db, n).base, np.memmap)]
    assert mapped, "the pattern tables are memory-mapped"
    before = _rss_file_bytes()
    if before is None:
        pytest.skip("no /proc/self/status RssFile: not Linux")
    db.page_in()
    grown = _rss_file_bytes() - before
    assert grown >= 0.99 * sum(getattr(db, n).nbytes for n in mapped)
    for name in db._ARRAYS:
        np.testing.assert_array_equal(getattr(db, name), getattr(built, name))
    built.page_in()  # a database built in memory maps nothing: nothing to read
