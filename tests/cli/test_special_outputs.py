"""No command writes over a device, a FIFO, a socket or a symbolic link to one of them.

Writing a temporary file and renaming it onto the output would replace a device or a FIFO given
as the output with a regular file (``--plot /dev/null`` run as root replaced the system's
``/dev/null``). Every command that writes refuses such a path before any work, with one line
naming it (exit 2), and leaves it as it was. The special files are made here, in ``tmp_path``
(a FIFO, a character device with the numbers of the null device where the test may make one,
a symbolic link to the FIFO); never the system's ``/dev``.

Each case runs in-process through ``starsense.cli.main``: the refusal comes before the work,
so the whole table takes seconds.
"""

from __future__ import annotations

import os
import socket
import stat
from pathlib import Path

import pytest

from starsense._io import atomic_write, check_output, check_outputs_in
from starsense.cli import main
from starsense.errors import OutputError

#: what stands where the output goes
KINDS = ("fifo", "chardev", "link-to-fifo")

# fmt: off
#: (command line, the special file's name): ``{t}`` is the special file (a file output),
#: ``{d}`` the folder holding it (the command writes a file of that name into the folder),
#: ``{csv}`` a valid input catalogue. The special file is the output itself or one file of it.
CASES = [
    (["render", "--out", "{t}"], "f.png"),
    (["render", "--out", "{d}/f.png"], "f.png.json"),  # the truth beside the frame
    (["render", "--out", "{d}/f.png", "--sequence", "2", "--interval-s", "1"], "f_001.png"),
    (["solve", "--wcs", "{t}", "{d}/frame.png"], "frame.wcs"),
    (["solve", "--explain", "{t}", "{d}/frame.png"], "explain.png"),
    (["calibrate", "--out", "{t}", "{d}/frame.png"], "cal.toml"),
    (["characterize", "--out", "{t}", "{d}/frame.png"], "char.toml"),
    (["characterize", "--out", "{d}/char.toml", "--plot", "{t}", "{d}/frame.png"], "char.png"),
    (["slew", "tolerance", "--plot", "{t}"], "tol.png"),
    (["slew", "intensity", "--plot", "{t}"], "int.png"),
    (["slew", "study", "--plot", "{t}"], "study.png"),
    (["limit", "curve", "--plot", "{t}"], "curve.png"),
    (["availability", "static", "--plot", "{t}"], "static.png"),
    (["availability", "static", "--maps", "{d}"], "static_sparse.png"),
    (["availability", "dynamic", "--plot", "{t}"], "dyn.png"),
    (["availability", "dynamic", "--rates-deg-s", "0,1.5", "--maps", "{d}"],
     "dynamic_1.5degs.png"),
    (["availability", "track", "--plot", "{t}"], "track.png"),
    (["availability", "track", "--rate-deg-s", "2", "--maps", "{d}"], "track_2degs.png"),
    (["availability", "mission", "--plot", "{t}"], "mission.png"),
    (["report", "--out", "{t}"], "report"),
    (["datasheet", "--out", "{d}"], "st16_datasheet.json"),
    (["datasheet", "--out", "{d}"], "st16_nea_sky.png"),
    (["trade", "--vary", "exposure_s=0.1,0.2", "--out", "{d}"], "trade.csv"),
    (["trade", "--vary", "exposure_s=0.1,0.2", "--out", "{d}"], "trade_pareto_nea_vs_rate.png"),
    (["catalog", "import", "{csv}", "{t}"], "hats"),
    (["ecss", "--out", "{t}"], "statement.csv"),
    (["ecss", "--out", "{t}"], "statement.json"),
]
# fmt: on


def _ids(case) -> str:
    argv, name = case
    words = [a for a in argv if not a.startswith(("{", "-")) and "=" not in a]
    return "-".join(words[:2]) + f":{name}"


def _make(kind: str, folder: Path, name: str) -> Path:
    """Make the special file ``folder/name`` of ``kind``; return it (skip if not permitted)."""
    path = folder / name
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "chardev":
        try:  # the null device's numbers: a node made here, in the test's folder
            os.mknod(path, 0o600 | stat.S_IFCHR, os.makedev(1, 3))
        except PermissionError:
            pytest.skip("making a character device needs root (CAP_MKNOD)")
    else:
        os.mkfifo(folder / ".the-fifo")
        os.symlink(".the-fifo", path)
    return path


def _still(kind: str, path: Path) -> None:
    """Assert the special file is what it was: not replaced, not removed."""
    if kind == "link-to-fifo":
        assert path.is_symlink() and os.readlink(path) == ".the-fifo"
        assert stat.S_ISFIFO(os.stat(path).st_mode)
    elif kind == "fifo":
        assert stat.S_ISFIFO(os.lstat(path).st_mode)
    else:
        st = os.lstat(path)
        assert stat.S_ISCHR(st.st_mode) and st.st_rdev == os.makedev(1, 3)


_WHAT = {
    "fifo": "a FIFO",
    "chardev": "a character device",
    "link-to-fifo": "a symbolic link to a FIFO",
}


@pytest.fixture
def catalogue_csv(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("input")
    path = d / "stars.csv"
    path.write_text("ra,dec,V\n10.0,20.0,3.0\n11.0,21.0,4.0\n")
    return path


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize(("argv", "name"), CASES, ids=[_ids(c) for c in CASES])
def test_writer_refuses_a_special_output(argv, name, kind, tmp_path, catalogue_csv, capsys):
    out = tmp_path / "out"
    out.mkdir()
    special = _make(kind, out, name)
    before = sorted(p.name for p in out.iterdir())
    args = [a.format(t=special, d=out, csv=catalogue_csv) for a in argv]
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # one line, no traceback
    assert str(special) in lines[0] and _WHAT[kind] in lines[0], lines[0]
    _still(kind, special)
    assert sorted(p.name for p in out.iterdir()) == before  # nothing written beside it


# -- the check itself ---------------------------------------------------------------------------


def test_check_output_accepts_new_paths_regular_files_and_links_to_them(tmp_path):
    regular = tmp_path / "old.png"
    regular.write_bytes(b"old")
    (tmp_path / "link.png").symlink_to("old.png")
    (tmp_path / "dangling.png").symlink_to("nowhere.png")
    for name in ("new.png", "old.png", "link.png", "dangling.png"):
        assert check_output(tmp_path / name, "--plot") == tmp_path / name


def test_check_output_names_a_socket(tmp_path):
    path = tmp_path / "s.png"
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.bind(str(path))
        with pytest.raises(OutputError, match=r"s\.png: it is a socket, not a regular file"):
            check_output(path, "--plot")
    assert stat.S_ISSOCK(os.lstat(path).st_mode)


def test_check_output_a_special_file_where_a_folder_goes(tmp_path):
    os.mkfifo(tmp_path / "r")
    with pytest.raises(OutputError, match=r"it is a FIFO \(named pipe\), not a directory"):
        check_output(tmp_path / "r", "--out", directory=True)


def test_check_outputs_in_names_the_file_in_the_folder(tmp_path):
    os.mkfifo(tmp_path / "b.csv")
    with pytest.raises(OutputError, match=r"--out .*b\.csv: it is a FIFO"):
        check_outputs_in(tmp_path, ["a.csv", "b.csv"], "--out")


def test_a_fifo_made_during_the_write_is_not_replaced(tmp_path):
    # the check before the work passes (a new path); a FIFO made there meanwhile is refused
    # at the rename, and the temporary file is removed
    target = tmp_path / "t.json"
    with pytest.raises(OutputError, match=r"t\.json: it is a FIFO"), atomic_write(target) as fh:
        fh.write("{}")
        os.mkfifo(target)
    assert stat.S_ISFIFO(os.lstat(target).st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["t.json"]


def test_check_outputs_in_a_folder_not_made_yet(tmp_path):
    folder = tmp_path / "new" / "maps"
    assert check_outputs_in(folder, ["a.png"], "--maps") == [folder / "a.png"]
    assert not (tmp_path / "new").exists()  # checked, not made
