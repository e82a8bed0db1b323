"""Pieces shared by the command-line modules: common options, number lists, output."""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Callable, Iterator
from typing import Annotated, Any

import numpy as np
import typer

from starsense.errors import InputError

JsonOpt = Annotated[bool, typer.Option("--json", help="Print machine-readable JSON.")]
SensorOpt = Annotated[
    str, typer.Option("--sensor", help="Sensor preset (st16, esa_blackfly) or a TOML file.")
]
SeedOpt = Annotated[int, typer.Option("--seed", help="Root seed (results are reproducible).")]
CatalogOpt = Annotated[
    str,
    typer.Option(
        "--catalog",
        help="hipparcos (bundled), bsc5:PATH (the ST-16 paper's Yale Bright Star Catalogue), "
        "hip_main:PATH, tycho2:PATH, twomass:PATH, gaia:PATH.",
    ),
]


def parse_floats(text: str | None, option: str, n: int | None = None) -> list[float] | None:
    """Parse "1,2.5,3" given to ``option``; exactly ``n`` values when n is given."""
    if text is None:
        return None
    try:
        values = [float(p) for p in text.split(",") if p.strip() != ""]
    except ValueError:
        raise InputError(f"{option} expects comma-separated numbers, got {text!r}") from None
    if not values or (n is not None and len(values) != n):
        want = f"{n} values" if n else "at least one value"
        raise InputError(f"{option} expects {want}, got {text!r}")
    if not all(np.isfinite(values)):
        raise InputError(f"{option} values must be finite, got {text!r}")
    return values


def emit(payload: dict, as_json: bool, lines: list[str]) -> None:
    """Print ``payload`` as JSON, or the human-readable ``lines``."""
    if as_json:
        typer.echo(json.dumps(payload, indent=2))
    else:
        for line in lines:
            typer.echo(line)


@contextlib.contextmanager
def progress_bar() -> Iterator[Callable[[str, int, int], None]]:
    """A rich progress bar on stderr, one task per label (hidden when stderr is not a
    terminal); yields ``update(label, done, total)``.
    """
    from rich.progress import Progress

    with Progress(transient=True, disable=not sys.stderr.isatty()) as bar:
        tasks: dict[str, Any] = {}

        def update(label: str, done: int, total: int) -> None:
            if label not in tasks:
                tasks[label] = bar.add_task(label, total=total)
            bar.update(tasks[label], completed=done, total=total)

        yield update
