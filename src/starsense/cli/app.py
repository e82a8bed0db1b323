"""Command line: parse, load, call the API, print or write results. No physics here.

User errors (:class:`~starsense.errors.StarsenseError`) are printed as one line on stderr with exit
status 2; no traceback.
"""

from __future__ import annotations

import sys

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
    from starsense.cli.catalog import catalog_app
    from starsense.cli.frames import montecarlo, render
    from starsense.cli.guide_stars import guide_stars_app
    from starsense.cli.limit import limit_app
    from starsense.cli.report import report
    from starsense.cli.slew import slew_app
    from starsense.cli.solve import solve

    app.add_typer(limit_app, name="limit")
    app.add_typer(slew_app, name="slew")
    app.command("render")(render)
    app.command("solve")(solve)
    app.command("montecarlo")(montecarlo)
    app.command("report")(report)
    app.add_typer(availability_app, name="availability")
    app.add_typer(guide_stars_app, name="guide-stars")
    app.add_typer(catalog_app, name="catalog")


_register_subapps()


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
        0 on success, 1 for a negative answer (a frame that does not solve), 2 for bad input.
    """
    try:
        app(args=argv, prog_name="starsense")  # standalone mode: ends with SystemExit
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except StarsenseError as exc:
        typer.echo(f"error: {exc}", err=True)
        return 2
    except FileNotFoundError as exc:
        typer.echo(f"error: file not found: {exc.filename}", err=True)
        return 2
    return 0


def _console_main() -> None:  # pragma: no cover - thin wrapper for the console script
    sys.exit(main())


if __name__ == "__main__":  # pragma: no cover
    _console_main()
