"""starsense._io: the one atomic write (temporary file beside the target, fsync, rename)."""

from __future__ import annotations

import errno
import os

import pytest

from starsense._io import atomic_path, atomic_write, file_mode
from starsense.errors import OutputError


@pytest.fixture(params=[0o022, 0o077, 0o002], ids=["umask022", "umask077", "umask002"])
def umask(request):
    old = os.umask(request.param)
    try:
        yield request.param
    finally:
        os.umask(old)


def _mode(path) -> int:
    return path.stat().st_mode & 0o777


def test_file_mode_follows_umask(umask):
    assert file_mode() == 0o666 & ~umask
    assert os.umask(umask) == umask  # file_mode leaves the umask as it was


def test_atomic_write_text_mode_and_content(tmp_path, umask):
    target = tmp_path / "out.json"
    with atomic_write(target) as fh:
        fh.write("héllo\n")
    assert target.read_text(encoding="utf-8") == "héllo\n"
    assert _mode(target) == 0o666 & ~umask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_atomic_write_binary(tmp_path, umask):
    target = tmp_path / "out.bin"
    with atomic_write(target, "wb") as fh:
        fh.write(b"\x00\x01\x02")
    assert target.read_bytes() == b"\x00\x01\x02"
    assert _mode(target) == 0o666 & ~umask


def test_atomic_path_for_writers_that_take_a_name(tmp_path, umask):
    target = tmp_path / "figure.png"
    with atomic_path(target, suffix=".png") as tmp:
        assert tmp.parent == tmp_path and tmp.name.endswith(".png") and tmp != target
        assert not target.exists()  # nothing at the target until the block succeeds
        tmp.write_bytes(b"png")
    assert target.read_bytes() == b"png"
    assert _mode(target) == 0o666 & ~umask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figure.png"]


def test_replaces_an_existing_file_with_new_permissions(tmp_path, umask):
    target = tmp_path / "out.txt"
    target.write_text("old")
    os.chmod(target, 0o600)
    with atomic_write(target) as fh:
        fh.write("new")
    assert target.read_text() == "new"
    assert _mode(target) == 0o666 & ~umask


def test_error_leaves_no_partial_file_and_no_temporary(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError, match="boom"), atomic_write(target) as fh:
        fh.write("partial")
        raise RuntimeError("boom")
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []


def test_error_keeps_the_previous_file(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("previous")
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert target.read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_writer_that_removes_its_temporary_is_not_an_error(tmp_path):
    # a failing writer may delete its own output before raising: the cleanup must not mask it
    target = tmp_path / "out.txt"
    with pytest.raises(ValueError, match="writer failed"), atomic_path(target) as tmp:
        tmp.unlink()
        raise ValueError("writer failed")
    assert list(tmp_path.iterdir()) == []


def test_bad_mode_is_refused(tmp_path):
    with (
        pytest.raises(ValueError, match="mode must be 'w' or 'wb'"),
        atomic_write(tmp_path / "x", "a"),
    ):
        pass
    assert list(tmp_path.iterdir()) == []


def test_missing_directory_is_an_error_without_leftovers(tmp_path):
    with (
        pytest.raises(OutputError, match=r"nosuch/x\.txt: directory .*nosuch does not exist"),
        atomic_write(tmp_path / "nosuch" / "x.txt") as fh,
    ):
        fh.write("x")
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_names_the_users_path_not_the_temporary(tmp_path):
    target = tmp_path / "out.txt"
    with pytest.raises(OutputError) as info, atomic_path(target) as tmp:
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
    assert str(info.value) == f"cannot write {target}: No space left on device"
    assert list(tmp_path.iterdir()) == []


def test_an_unrelated_error_inside_the_block_is_not_rewritten(tmp_path):
    with pytest.raises(FileNotFoundError), atomic_path(tmp_path / "out.txt"):
        open(tmp_path / "some-input-that-is-missing")
    assert list(tmp_path.iterdir()) == []


def test_target_that_is_a_directory_is_refused_before_anything_is_written(tmp_path):
    (tmp_path / "out").mkdir()
    with pytest.raises(OutputError, match=r"cannot write output .*out: it is a directory"):
        with atomic_write(tmp_path / "out") as fh:
            fh.write("x")  # pragma: no cover
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
