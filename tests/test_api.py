"""The front door: ``import starsense as ss`` gives the names a user needs, each documented,
and the README's Python example runs."""

from __future__ import annotations

import doctest
import inspect
import pydoc
import subprocess
import sys
from pathlib import Path

import pytest

import starsense as ss

README = Path(__file__).resolve().parents[1] / "README.md"
SHARED = Path(__file__).resolve().parents[2] / "shared"

#: the names the front door promises (a user's first ten lines use them)
NAMES = (
    "load_sensor",
    "load_catalog",
    "Sensor",
    "Catalog",
    "attitude_from_radec_roll",
    "render_frame",
    "Solver",
    "Solution",
    "Tracker",
    "calibrate",
    "datasheet",
    "Datasheet",
    "compare",
    "predict",
    "montecarlo",
    "availability",
    "slew_tolerance",
    "sky_limit",
)


def test_import_is_light():
    """``import starsense`` loads none of the stages (the names load on first use)."""
    code = (
        "import sys, starsense; print(sorted(m for m in sys.modules if m.startswith('starsense')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "['starsense']"


@pytest.mark.parametrize("name", NAMES)
def test_name_is_exported_and_documented(name):
    assert name in ss.__all__
    value = getattr(ss, name)
    doc = inspect.getdoc(value) or ""
    assert len(doc.splitlines()) >= 1 and doc.strip(), f"{name} has no docstring"
    if inspect.isfunction(value):
        # numpydoc: every function with parameters says what they are
        if inspect.signature(value).parameters:
            assert "Parameters\n----------" in doc, f"{name}: no numpydoc Parameters section"
        assert "Returns\n-------" in doc, f"{name}: no numpydoc Returns section"
    if inspect.isclass(value):
        # numpydoc: a class says what it is built from (Parameters) or holds (Attributes)
        assert "Parameters\n----------" in doc or "Attributes\n----------" in doc, name
    if inspect.ismodule(value):
        for entry in ("static", "dynamic", "mission"):
            fn = getattr(value, entry)
            assert "Parameters\n----------" in (inspect.getdoc(fn) or ""), f"{name}.{entry}"


def test_help_lists_every_name():
    text = pydoc.render_doc(ss, renderer=pydoc.plaintext)
    missing = [n for n in NAMES if n not in text]
    assert missing == []


def test_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'Solvr'"):
        ss.Solvr  # noqa: B018


@pytest.mark.skipif(not README.is_file(), reason="README.md not found beside the tests")
@pytest.mark.slow
def test_readme_python_example_runs():
    """The README's Python example is a doctest: it runs as written, with its printed output."""
    result = doctest.testfile(
        str(README), module_relative=False, optionflags=doctest.ELLIPSIS, verbose=False
    )
    assert result.attempted >= 8, "the README's Python example is missing"
    assert result.failed == 0


#: the front door's entries that draw random numbers (frames, trials, sky samples)
STOCHASTIC = ("render_frame", "datasheet", "compare", "predict", "montecarlo", "slew_tolerance")


@pytest.mark.parametrize("name", STOCHASTIC)
def test_every_random_entry_takes_rng(name):
    """Randomness is an ``rng`` everywhere (an int seed or a Generator): one keyword to learn."""
    assert "rng" in inspect.signature(getattr(ss, name)).parameters
    for entry in ("static", "dynamic", "mission"):
        assert "rng" in inspect.signature(getattr(ss.availability, entry)).parameters


def test_version_is_the_packages():
    """``starsense.__version__`` is the version pyproject.toml builds (one release, one number)."""
    import tomllib

    project = tomllib.loads((README.parent / "pyproject.toml").read_text())["project"]
    assert ss.__version__ == project["version"]
