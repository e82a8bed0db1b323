"""Every command's --help wraps its prose at the terminal's width, never mid-sentence."""

from __future__ import annotations

import itertools

import pytest

from starsense.cli import main
from starsense.cli.app import COMMANDS, SUBCOMMANDS, build_app
from starsense.cli.helptext import reflow

WIDTH = 80  # the narrowest common terminal; the docstrings are written to 99 columns


def _all_commands() -> list[list[str]]:
    out = [[]]
    app = build_app()
    groups = {g.name: g.typer_instance for g in app.registered_groups}
    for name in COMMANDS:
        out.append([name])
        if name in groups:
            subs = [c.name or c.callback.__name__ for c in groups[name].registered_commands]
            out += [[name, sub] for sub in dict.fromkeys([*subs, *SUBCOMMANDS.get(name, {})])]
    return out


def _early_breaks(text: str) -> list[str]:
    """Lines of the prose (above the option panels) broken before the width was used.

    Rich wraps greedily: a line ends only when the next word would not fit. A line followed by
    more prose whose next word would have fitted on it was broken by the docstring's own line
    break. (Margin: rich pads the text by one column each side; 4 columns allowed.)
    """
    prose = [line.rstrip() for line in text.split("\u256d")[0].splitlines()]
    bad = []
    for a, b in itertools.pairwise(prose):
        if not a.strip() or not b.strip() or a.strip().startswith("Usage:"):
            continue
        if len(a.strip()) + 1 + len(b.split()[0]) < WIDTH - 4:
            bad.append(f"{a.strip()!r} / {b.strip()!r}")
    return bad


@pytest.mark.parametrize("argv", _all_commands(), ids=lambda a: " ".join(a) or "starsense")
def test_help_prose_is_not_broken_mid_sentence(argv, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", str(WIDTH))
    assert main([*argv, "--help"]) == 0
    out = capsys.readouterr().out
    assert "Usage:" in out
    assert _early_breaks(out) == []


def test_reflow_joins_prose_and_keeps_blocks():
    doc = """Title line.

    A paragraph written
    on two lines.

    \b
    kept: line one
    kept: line two

    A list:
    - first
    - second
    \f
    hidden
    line
    """
    got = reflow(doc)
    assert "A paragraph written on two lines." in got
    assert "\b\nkept: line one\nkept: line two" in got
    assert "A list:\n- first\n- second" in got
    assert got.endswith("\f\nhidden\nline")
    assert reflow(None) is None
