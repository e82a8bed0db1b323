"""Command line: parse, load, call the API, print or write results. No physics here.

User errors (:class:`~starsense.errors.StarsenseError`) are printed as one line on stderr with exit
status 2; no traceback. SIGTERM is handled like Ctrl-C: the command unwinds (temporary files are
removed, an earlier output stays as it was) and the process exits with status 143 (128 + 15).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator

import typer

from starsense.errors import StarsenseError

app = typer.Typer(
    name="starsense",
    help="Star-tracker engineering: how good a star sensor can be, and how good it is.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _register_subapps() -> None:
    from starsense.cli.availability import availability_app
    from starsense.cli.calibrate import calibrate
    from starsense.cli.catalog import catalog_app
    from starsense.cli.datasheet import datasheet
    from starsense.cli.frames import montecarlo, render
    from starsense.cli.guide_stars import guide_stars_app
    from starsense.cli.limit import limit_app
    from starsense.cli.mission import mission
    from starsense.cli.report import report
    from starsense.cli.slew import slew_app
    from starsense.cli.solve import solve
    from starsense.cli.track import track

    app.add_typer(limit_app, name="limit")
    app.add_typer(slew_app, name="slew")
    app.command("render")(render)
    app.command("solve")(solve)
    app.command("calibrate")(calibrate)
    app.command("montecarlo")(montecarlo)
    app.command("datasheet")(datasheet)
    app.command("track")(track)
    app.command("report")(report)
    availability_app.command("mission")(mission)
    app.add_typer(availability_app, name="availability")
    app.add_typer(guide_stars_app, name="guide-stars")
    app.add_typer(catalog_app, name="catalog")


_register_subapps()


class Terminated(BaseException):
    """SIGTERM arrived: unwind like KeyboardInterrupt (a BaseException, so no handler eats it)."""


#: exit status after SIGTERM (the shell's 128 + signal number)
EXIT_TERMINATED = 128 + signal.SIGTERM


def _on_sigterm(signum: int, frame: object) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a second TERM must not cut the cleanup short
    raise Terminated


@contextlib.contextmanager
def _sigterm_unwinds() -> Iterator[None]:
    """Turn SIGTERM into :class:`Terminated` while the command runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def main(argv: list[str] | None = None) -> int:
    """Run the command line on ``argv``; return the exit status.

    User errors (:class:`~starsense.errors.StarsenseError`, a missing file) become one line on
    stderr and status 2. Usage errors (unknown option, bad type) are reported by typer itself,
    also with status 2.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 1 for a negative answer (a frame that does not solve), 2 for bad input,
        143 after SIGTERM.
    """
    try:
        with _sigterm_unwinds():
            app(args=argv, prog_name="starsense")  # standalone mode: ends with SystemExit
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except StarsenseError as exc:
        typer.echo(f"error: {exc}", err=True)
        return 2
    except FileNotFoundError as exc:
        typer.echo(f"error: file not found: {exc.filename}", err=True)
        return 2
    except Terminated:
        typer.echo("error: terminated (SIGTERM); nothing written", err=True)
        return EXIT_TERMINATED
    return 0


def _console_main() -> None:  # pragma: no cover - thin wrapper for the console script
    sys.exit(main())


if __name__ == "__main__":  # pragma: no cover
    _console_main()
