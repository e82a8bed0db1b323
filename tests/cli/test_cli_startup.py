"""Start-up of the command line: only the invoked command's module is imported, and the
listings read from the modules' source print what the real commands print."""

from __future__ import annotations

import subprocess
import sys

import pytest
from typer.testing import CliRunner

from starsense.cli.app import COMMANDS, app_for, build_app
from starsense.cli.listing import group_listing

runner = CliRunner()

GROUPS = [name for name, where in COMMANDS.items() if group_listing(*where) is not None]

LISTINGS = [
    [],
    ["--help"],
    ["no-such-command"],
    *([g] for g in GROUPS),
    *([g, "--help"] for g in GROUPS),
    *([g, "no-such-command"] for g in GROUPS),
]


def test_every_group_is_read_from_its_source():
    assert set(GROUPS) == {"limit", "slew", "availability", "guide-stars", "catalog"}


@pytest.mark.parametrize("args", LISTINGS, ids=lambda a: " ".join(a) or "no-arguments")
def test_listing_prints_what_the_full_app_prints(args):
    full = runner.invoke(build_app(), args, prog_name="starsense")
    listed = runner.invoke(app_for(args), args, prog_name="starsense")
    assert (listed.exit_code, listed.output) == (full.exit_code, full.output)


def _loaded(*argv: str, every_module: bool = False) -> set[str]:
    """The modules a command imports: the heavy libraries and starsense.cli's, or all."""
    code = (
        "import contextlib, io, sys\n"
        "from starsense.cli import main\n"
        "quiet = io.StringIO()\n"
        "with contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):\n"
        "    try:\n"
        "        main(sys.argv[2:])\n"
        "    except SystemExit as e:\n"
        "        assert not e.code, quiet.getvalue()\n"
        "mods = set(sys.modules)\n"
        "heavy = {m.split('.')[0] for m in mods} & {'scipy', 'matplotlib', 'astropy'}\n"
        "cli = {m for m in mods if m.startswith('starsense.cli.')}\n"
        "print(' '.join(sorted(mods if sys.argv[1] == 'all' else heavy | cli)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, "all" if every_module else "some", *argv],
        capture_output=True,
        text=True,
        check=True,
    )
    return set(out.stdout.split())


@pytest.mark.parametrize("argv", [["--help"], ["limit", "--help"], ["availability"]])
def test_listings_import_no_command(argv):
    # helptext: the help's paragraphs reflowed (the standard library only)
    assert _loaded(*argv) == {
        "starsense.cli.app",
        "starsense.cli.helptext",
        "starsense.cli.listing",
    }


def test_a_command_imports_its_module_only():
    loaded = {m for m in _loaded("solve", "--help") if m.startswith("starsense.cli.")}
    assert loaded == {
        "starsense.cli.app",
        "starsense.cli.attitude_json",
        "starsense.cli.common",
        "starsense.cli.helptext",
        "starsense.cli.listing",
        "starsense.cli.solve",
    }


def test_solving_a_frame_imports_nothing_it_does_not_use(shared_dir):
    # `starsense solve FRAME --sensor ...` as a user runs it: a frame's solve pays for what it
    # needs (numpy, scipy.spatial's rotations, which import all of scipy.spatial, scipy.ndimage,
    # tifffile), not for the least-squares fits, the spline and PCHIP interpolators, the tracker,
    # the figures, the progress bars (~0.17 s of the command's start-up), Pillow (the TIFF's
    # header time is read with tifffile) or pydantic (typer >= 0.28 coerces options through it:
    # ~0.1 s). The database, built once by the first run, is left out of the second: building it
    # converts catalogue magnitudes (PCHIP); loading it from the cache does not.
    frames = sorted((shared_dir / "data" / "images" / "esa").glob("*.tiff"))
    if not frames:
        pytest.skip(f"no ESA frames in {shared_dir}")
    argv = ["solve", str(frames[0]), "--sensor", "esa_blackfly"]
    loaded = set()
    for _run in range(2):
        loaded = _loaded(*argv, every_module=True)
    assert {"starsense.solve.solver", "starsense.detect.threshold", "scipy.spatial"} <= loaded
    unused = {
        "scipy.interpolate",
        "scipy.optimize",
        "starsense.solve.tracking",
        "matplotlib",
        "rich",  # the progress bar's, drawn only for a batch on a terminal
        "PIL",
        "pydantic",
    }
    assert not loaded & unused, sorted(loaded & unused)


def test_the_listing_is_read_once_and_again_when_its_module_changes(tmp_path, monkeypatch):
    # a command group in a module of its own: read from its source, kept in the cache file,
    # read from there while the file is unchanged, and from the source again once it changes
    from starsense.cli import listing

    monkeypatch.setenv("STARSENSE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.syspath_prepend(str(tmp_path))
    listing._cache.cache_clear()
    monkeypatch.setattr(listing, "_unsaved", [])
    source = tmp_path / "listed_group.py"
    source.write_text(
        'import typer\ngroup = typer.Typer(help="Things.")\n\n\n'
        '@group.command()\ndef one():\n    """The first."""\n'
    )
    first = group_listing("listed_group", "group")
    assert first.commands == (("one", "The first."),)
    listing.save_cache()
    assert (tmp_path / "cache" / "cli" / "cli-listing.json").is_file()
    listing._cache.cache_clear()  # a new process: the entries come from the file
    monkeypatch.setattr(listing, "_tree", lambda module: pytest.fail("parsed again"))
    assert group_listing("listed_group", "group") == first
    monkeypatch.undo()  # the source changes (another size): it is read again
    monkeypatch.setenv("STARSENSE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.syspath_prepend(str(tmp_path))
    listing._tree.cache_clear()
    source.write_text(source.read_text().replace("The first.", "The first one."))
    assert group_listing("listed_group", "group").commands == (("one", "The first one."),)


def test_an_unwritable_cache_only_costs_time(tmp_path, monkeypatch):
    from starsense.cli import listing

    blocked = tmp_path / "file"
    blocked.write_text("")  # the cache directory would be under a file: cannot be made
    monkeypatch.setenv("STARSENSE_CACHE_DIR", str(blocked))
    listing._cache.cache_clear()
    monkeypatch.setattr(listing, "_unsaved", [True])
    listing.save_cache()  # says nothing, raises nothing
    full = runner.invoke(build_app(), ["--help"], prog_name="starsense")
    listed = runner.invoke(app_for(["--help"]), ["--help"], prog_name="starsense")
    assert listed.output == full.output
    listing._cache.cache_clear()
