"""Pieces shared by the command-line modules: options, edge checks, output, the progress bar.

* Options every command group uses (``--sensor``, ``--catalog``, ``--json``, ``--seed``,
  ``--dask`` ...) are declared here once, as :data:`typing.Annotated` aliases.
* Edge checks (:func:`option_float`, :func:`option_int`, :func:`parse_floats`) validate an
  option's value with :mod:`starsense._validate` under the *option's* name (``--rate-deg-s``),
  before the command converts degrees to radians and calls the library, whose own messages
  name its parameters (``rate_rad_s``).
* :func:`progress_bar` is the one progress bar of the command line.
"""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from starsense._io import check_output, json_text
from starsense._validate import check_int, check_scalar
from starsense.errors import InputError

__all__ = [
    "CatalogOpt",
    "ColourOpt",
    "DaskOpt",
    "DiameterOpt",
    "ExposureOpt",
    "JsonOpt",
    "ModelOpt",
    "ProgressBar",
    "ScaleCatalogOpt",
    "SeedOpt",
    "SensorOpt",
    "emit",
    "option_float",
    "option_int",
    "output_dir",
    "output_file",
    "parse_floats",
    "progress_bar",
    "seed_option",
    "step_grid",
]

# -- options ------------------------------------------------------------------------------------

JsonOpt = Annotated[bool, typer.Option("--json", help="Print machine-readable JSON.")]
SensorOpt = Annotated[
    str, typer.Option("--sensor", help="Sensor preset (st16, esa_blackfly) or a TOML file.")
]


def seed_option(value: int) -> int:
    """Option callback of every ``--seed``: an integer >= 0, checked before any work.

    Raises
    ------
    InputError
        Naming ``--seed`` and the value (NumPy's generators refuse negative seeds).
    """
    return check_int(value, "--seed", 0)


SeedOpt = Annotated[
    int,
    typer.Option(
        "--seed", help="Root seed, >= 0 (results are reproducible).", callback=seed_option
    ),
]
CatalogOpt = Annotated[
    str,
    typer.Option(
        "--catalog",
        help="hipparcos (bundled), bsc5:PATH (the ST-16 paper's Yale Bright Star Catalogue), "
        "hip_main:PATH, tycho2:PATH, twomass:PATH, gaia:PATH.",
    ),
]
ScaleCatalogOpt = Annotated[
    str,
    typer.Option(
        "--catalog",
        help="hipparcos (bundled), bsc5:PATH, hip_main:PATH, tycho2:PATH, twomass:PATH, "
        "gaia:PATH, or hats:PATH_OR_URL (a HATS catalogue, processed on Dask; e.g. "
        "hats:https://data.lsdb.io/hats/gaia_dr3, hats:https://data.lsdb.io/hats/two_mass).",
    ),
]
DaskOpt = Annotated[
    str | None,
    typer.Option(
        "--dask",
        help="Dask cluster for hats: catalogues: local (default: this machine, one worker per "
        "CPU), local:N, or a scheduler address tcp://HOST:PORT.",
    ),
]
DiameterOpt = Annotated[
    float, typer.Option("--diameter-m", help="Aperture (ideal sensor) diameter D, metres.")
]
ExposureOpt = Annotated[float, typer.Option("--exposure-s", help="Exposure time t, seconds.")]
ColourOpt = Annotated[
    str | None,
    typer.Option("--colour", help="Colour system: B-V, V-I, BT-VT, J-H, J-Ks, H-Ks, BP-RP."),
]
ModelOpt = Annotated[
    str, typer.Option("--model", help="Sensitivity model: reed, liebe (or blackbody to render).")
]

# -- edge checks --------------------------------------------------------------------------------


def option_float(
    value: object,
    option: str,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    allow_inf: bool = False,
) -> float:
    """Check a number given to ``option`` (finite, within ``[lo, hi]``) and return it.

    Parameters
    ----------
    value : object
        The option's value, in the option's own unit (degrees for ``--ra-deg``).
    option : str
        The option, as the user typed it (``"--rate-deg-s"``): the message names it.
    lo, hi : float or None
        Bounds, in the option's unit; None for none.
    lo_open, hi_open : bool
        Exclude the bound itself.
    allow_inf : bool
        Accept +-inf (still subject to the bounds).

    Returns
    -------
    float

    Raises
    ------
    InputError
        Naming ``option``, its value and the allowed range.
    """
    return check_scalar(
        value, option, lo, hi, lo_open=lo_open, hi_open=hi_open, allow_inf=allow_inf
    )


def option_int(
    value: object, option: str, minimum: int | None = None, maximum: int | None = None
) -> int:
    """Check an integer given to ``option`` (within the bounds given) and return it.

    Raises
    ------
    InputError
        Naming ``option`` and its value.
    """
    return check_int(value, option, minimum, maximum)


def parse_floats(
    text: str | None,
    option: str,
    n: int | None = None,
    lo: float | None = None,
    hi: float | None = None,
) -> list[float] | None:
    """Parse ``"1,2.5,3"`` given to ``option``: finite numbers, exactly ``n`` of them if given.

    Parameters
    ----------
    text : str or None
        The option's value; None (option not given) is returned as is.
    option : str
        The option's name, for the messages.
    n : int, optional
        The number of values required.
    lo, hi : float, optional
        Bounds every value must respect (closed), in the option's unit.

    Returns
    -------
    list of float or None
    """
    if text is None:
        return None
    parts = text.split(",")
    if text.strip() and any(not p.strip() for p in parts):  # "1,,2", "1,2,": a lost value
        raise InputError(f"{option} has an empty element in {text!r}; give numbers between commas")
    try:
        values = [float(p) for p in parts if p.strip() != ""]
    except ValueError:
        raise InputError(f"{option} expects comma-separated numbers, got {text!r}") from None
    if not values or (n is not None and len(values) != n):
        want = f"{n} values" if n else "at least one value"
        raise InputError(f"{option} expects {want}, got {text!r}")
    if not all(np.isfinite(values)):
        raise InputError(f"{option} values must be finite, got {text!r}")
    if lo is not None or hi is not None:
        for v in values:
            check_scalar(v, option, lo, hi)
    return values


def step_grid(lo: float, hi: float, step: object, option: str, min_step: float) -> np.ndarray:
    """Return ``lo, lo + step, ...`` up to ``hi`` (``hi`` itself when the step divides the span).

    Built from a count, like :func:`numpy.linspace`: no floating end point past ``hi`` (as
    ``arange`` gives for 0.01 over [-90, 90]), and a step below ``min_step`` is refused in one
    line before anything is allocated.

    Parameters
    ----------
    lo, hi : float
        The ends, in the option's unit.
    step : object
        The option's value.
    option : str
        The option, for the message.
    min_step : float
        The finest step allowed.

    Returns
    -------
    ndarray, shape (n,)
    """
    span = hi - lo
    step = option_float(step, option, min_step, span)
    n = round(span / step)
    if not math.isclose(n * step, span, rel_tol=1e-9):
        n = math.floor(span / step)
    return np.clip(lo + step * np.arange(n + 1), lo, hi)


# -- output -------------------------------------------------------------------------------------


def output_file(param: typer.CallbackParam, value: Path | None) -> Path | None:
    """Option callback: check an output file's place before any work (``callback=output_file``).

    Raises
    ------
    OutputError
        Naming the option and the path: a missing or read-only directory, a directory given
        where a file goes.
    """
    if value is not None:
        check_output(value, param.opts[0] if param.opts else param.name)
    return value


def output_dir(param: typer.CallbackParam, value: Path | None) -> Path | None:
    """Option callback: check an output directory's place before any work (``--out``, ``--maps``).

    Raises
    ------
    OutputError
        Naming the option and the path: a file where the directory goes, or no writable
        directory above it.
    """
    if value is not None:
        check_output(value, param.opts[0] if param.opts else param.name, directory=True)
    return value


def emit(payload: dict, as_json: bool, lines: list[str]) -> None:
    """Print ``payload`` as JSON (NaN and inf as ``null``), or the human-readable ``lines``."""
    if as_json:
        typer.echo(json_text(payload))  # NaN and inf as null: always valid JSON
    else:
        for line in lines:
            typer.echo(line)


class ProgressBar:
    """Progress of one command: a rich bar on stderr with one task per label.

    Call it as ``bar(label, done, total)`` (the callback the analyses and
    :mod:`starsense.scale` take), or get a ``(done, total)`` callback for one task with
    :meth:`task`. When hidden every call does nothing and :attr:`callback` is None, so a caller
    can skip the work of reporting altogether.
    """

    def __init__(self, bar: Any | None) -> None:
        self._bar = bar
        self._tasks: dict[str, Any] = {}

    @property
    def shown(self) -> bool:
        """Whether the bar is drawn (stderr is a terminal and the command asked for it)."""
        return self._bar is not None

    @property
    def callback(self) -> Callable[[str, int, int], None] | None:
        """Return ``self`` when shown, else None (for APIs that take an optional callback)."""
        return self if self.shown else None

    def _task(self, label: str, total: int | None) -> Any:
        if label not in self._tasks:
            self._tasks[label] = self._bar.add_task(label, total=total)
        return self._tasks[label]

    def __call__(self, label: str, done: int, total: int | None) -> None:
        """Set task ``label`` to ``done`` of ``total`` (the task appears on its first call)."""
        if self._bar is not None:
            self._bar.update(self._task(label, total), completed=done, total=total)

    def task(self, label: str, total: int | None = None) -> Callable[[int, int | None], None]:
        """Show task ``label`` now and return its ``progress(done, total)`` callback.

        Parameters
        ----------
        label : str
            What the task does ("Monte Carlo").
        total : int, optional
            Steps to do, if known now (an indeterminate bar otherwise).
        """
        if self._bar is not None:
            self._task(label, total)
        return lambda done, total: self(label, done, total)


@contextlib.contextmanager
def progress_bar(enabled: bool = True, *, unit: str | None = None) -> Iterator[ProgressBar]:
    """Yield the command's :class:`ProgressBar`: drawn on stderr, and removed when done.

    The bar is hidden when stderr is not a terminal, or when ``enabled`` is false (``--json``).

    Parameters
    ----------
    enabled : bool
        False to hide the bar whatever stderr is.
    unit : str, optional
        Counted items (``"partitions"``): each task then shows ``done/total unit`` instead of a
        percentage and time left.

    Yields
    ------
    ProgressBar
    """
    if not enabled or not sys.stderr.isatty():
        yield ProgressBar(None)
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    columns: tuple = ()
    if unit is not None:
        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn(unit),
        )
    # on stderr, as documented (rich's default console is stdout, where --json output goes)
    with Progress(*columns, transient=True, console=Console(stderr=True)) as bar:
        yield ProgressBar(bar)


def colour_clamp_note(system: str, ci: float, option: str, t: float | None = None) -> str | None:
    """Say what was clamped when a colour lies outside the paper's clamp (sec. 2.5), else None.

    ``t`` is the temperature the colour was given, K (default: the model's, for ``ci``).
    """
    from starsense.photometry import ColourModel  # noqa: PLC0415 - the commands that colour

    model = ColourModel(system)
    lo, hi = model.colour_limits
    if lo <= ci <= hi:
        return None
    t = float(model.temperature_k(ci)) if t is None else t
    return (
        f"{option} {ci:g} is outside [{lo:.4f}, {hi:.4f}], the {system} of black bodies at "
        f"{model.t_max_k:,.0f} K and {model.t_min_k:,.0f} K; the temperature is clamped to "
        f"{t:,.0f} K (Fialho & Mortari 2019, sec. 2.5)"
    )


#: the brightest magnitude a ``--max-mag`` may be: the Sun is -26.7; a limit below it keeps no
#: star at all (-1e308 rendered an empty frame, or chose no guide star, without a word)
BRIGHTEST_MAG = -30.0

#: the largest aperture and exposure an option takes: a sensor TOML's ranges (optics.aperture_m,
#: exposure_s); 1e308 overflowed the photon count, then the Fisher matrix (a traceback)
APERTURE_MAX_M = 10.0
EXPOSURE_MAX_S = 1e5


def check_aperture_options(diameter_m: float, exposure_s: float) -> None:
    """Check ``--diameter-m`` and ``--exposure-s``: finite, > 0 and within a sensor's ranges."""
    option_float(diameter_m, "--diameter-m", 0.0, APERTURE_MAX_M, lo_open=True)
    option_float(exposure_s, "--exposure-s", 0.0, EXPOSURE_MAX_S, lo_open=True)
