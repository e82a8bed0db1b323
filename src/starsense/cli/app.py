"""Command line: parse, load, call the API, print or write results. No physics here.

User errors (:class:`~starsense.errors.StarsenseError`) are printed as one line on stderr with exit
status 2; no traceback. Ctrl-C (SIGINT) and SIGTERM unwind the command (temporary files are
removed, an earlier output stays as it was) and the process exits with one line and status 130
or 143 (128 + the signal's number), from the start of :func:`main` on: the command's imports,
which take seconds, included. Importing this module takes no more than the standard library
(typer is loaded inside :func:`main`), so the moment before the handlers are in place is the
interpreter's own start-up.

Start-up: the command modules import the stages they call at their top, so the app imports
only the module of the command it runs (:data:`COMMANDS`, :func:`app_for`); the listings
(``starsense --help``, a group's name alone) are read from the modules' source
(:mod:`starsense.cli.listing`). ``app`` (every command registered) is built on first use.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from starsense.errors import (
    UNWIND,
    Interrupted,
    StarsenseError,
    Terminated,
    forget_signals,
    note_signal,
    one_line,
    signal_received,
)

if TYPE_CHECKING:
    import typer

#: the commands, in the order of ``starsense --help``: name -> (module, attribute), where the
#: attribute is a command function or a :class:`typer.Typer` group. A module is imported only when
#: its command runs (or for the full listing), so ``starsense solve`` loads what solving needs and
#: nothing of the other commands.
COMMANDS: dict[str, tuple[str, str]] = {
    "render": ("starsense.cli.frames", "render"),
    "solve": ("starsense.cli.solve", "solve"),
    "calibrate": ("starsense.cli.calibrate", "calibrate"),
    "characterize": ("starsense.cli.characterize", "characterize_command"),
    "montecarlo": ("starsense.cli.frames", "montecarlo"),
    "datasheet": ("starsense.cli.datasheet", "datasheet"),
    "ecss": ("starsense.cli.ecss", "ecss"),
    "trade": ("starsense.cli.trade", "trade"),
    "design": ("starsense.web.command", "design"),
    "track": ("starsense.cli.track", "track"),
    "report": ("starsense.cli.report", "report"),
    "limit": ("starsense.cli.limit", "limit_app"),
    "slew": ("starsense.cli.slew", "slew_app"),
    "availability": ("starsense.cli.availability", "availability_app"),
    "guide-stars": ("starsense.cli.guide_stars", "guide_stars_app"),
    "catalog": ("starsense.cli.catalog", "catalog_app"),
}

#: commands of a group that live in their own module: group -> {name: (module, attribute)},
#: registered after the group's own commands, and only when asked for (or for a listing)
SUBCOMMANDS: dict[str, dict[str, tuple[str, str]]] = {
    "availability": {"mission": ("starsense.cli.mission", "mission")},
}

HELP = "Star-tracker engineering: how good a star sensor can be, and how good it is."


def _group() -> None:
    pass  # the app is a group with its commands under it (the callback has no options)


def _typer():
    """Return the typer module, loaded on first use (after main's signal handlers are set)."""
    return importlib.import_module("typer")


def _empty_app() -> typer.Typer:
    app = _typer().Typer(
        name="starsense",
        help=HELP,
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
    )
    # a group even with one command registered (typer runs a lone command without its name)
    app.callback()(_group)
    return app


def _load(where: tuple[str, str]) -> Any:
    module, attribute = where
    return getattr(importlib.import_module(module), attribute)


def _add_subcommands(group: typer.Typer, name: str, subcommand: str | None) -> None:
    """Register the group's commands from other modules (:data:`SUBCOMMANDS`) that are needed."""
    own = {info.name for info in group.registered_commands}
    for sub, where in SUBCOMMANDS.get(name, {}).items():
        if sub in own:  # registered by an earlier build (the group is the module's object)
            continue
        if subcommand is None or subcommand == sub or subcommand not in own:
            group.command(sub)(_load(where))


def build_app(command: str | None = None, subcommand: str | None = None) -> typer.Typer:
    """Return the ``starsense`` app with ``command`` registered, or every command.

    Parameters
    ----------
    command : str, optional
        The command to run (the first argument): only its module is imported. None, or a name
        that is not a command (``--help``, a typo), registers them all, for the full listing and
        typer's own message about an unknown command.
    subcommand : str, optional
        The argument after a group's name (``mission`` in ``availability mission``): a command of
        the group kept in another module (:data:`SUBCOMMANDS`) is imported only when named, or
        when the group's commands are listed (None, ``--help``, an unknown name).

    Returns
    -------
    typer.Typer
    """
    app = _empty_app()
    selected = command in COMMANDS
    for name in [command] if selected else list(COMMANDS):
        target = _load(COMMANDS[name])
        if isinstance(target, _typer().Typer):
            _add_subcommands(target, name, subcommand if selected else None)
            app.add_typer(target, name=name)
        else:
            app.command(name)(target)
    return app


def app_for(args: list[str]) -> typer.Typer:
    """Return the app for the command line ``args``, importing no more than it needs.

    A command, or a command of a group, gets :func:`build_app` (its module imported). A
    listing (no argument, ``--help``, an unknown command; a group's name alone or with
    ``--help`` or an unknown command) is built from the modules' source
    (:mod:`starsense.cli.listing`) and prints the same text, without importing the commands.

    Parameters
    ----------
    args : list of str
        The arguments after the program name.

    Returns
    -------
    typer.Typer
    """
    listing = importlib.import_module("starsense.cli.listing")
    group_listing, listing_app = listing.group_listing, listing.listing_app
    command = args[0] if args else None
    if command not in COMMANDS:
        listed = listing_app(_empty_app(), COMMANDS, SUBCOMMANDS)
        return listed if listed is not None else build_app()
    group = group_listing(*COMMANDS[command])  # None for a command function
    if group is not None:
        names = {name for name, _ in group.commands} | set(SUBCOMMANDS.get(command, {}))
        if len(args) < 2 or args[1] not in names:
            listed = listing_app(_empty_app(), {command: COMMANDS[command]}, SUBCOMMANDS)
            if listed is not None:
                return listed
    return build_app(*args[:2])


def __getattr__(name: str) -> typer.Typer:
    """``app``: every command registered, built on first use (for tests and typer's runner)."""
    if name == "app":
        globals()["app"] = built = build_app()
        return built
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: exit status after SIGTERM (the shell's 128 + signal number)
EXIT_TERMINATED = 128 + signal.SIGTERM
#: exit status after Ctrl-C (SIGINT)
EXIT_INTERRUPTED = 128 + signal.SIGINT


def _on_signal(signum: int, frame: object) -> None:
    for s in UNWIND:  # a second signal must not cut the cleanup short
        signal.signal(s, signal.SIG_IGN)
    raise note_signal(signum)


@contextlib.contextmanager
def _signals_unwind() -> Iterator[None]:
    """Turn SIGINT and SIGTERM into :class:`Interrupted` and :class:`Terminated` while the
    command runs (main thread only)."""  # noqa: D205, D209
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, _on_signal) for s in UNWIND}
    hook = sys.unraisablehook
    sys.unraisablehook = _unwind_again(hook)
    try:
        yield
    finally:
        sys.unraisablehook = hook
        for s, handler in old.items():
            signal.signal(s, handler)


def _unwind_again(hook):
    """Return an unraisable-exception hook that raises a swallowed unwind again.

    Python reports an exception raised where it cannot propagate (an at-fork hook, a ``__del__``)
    and goes on: the unwind of a signal that landed there (logging's lock release after a process
    pool's fork) was lost, and the command ran to its end. The signal is sent again a moment
    later, from another thread (raised here, it would be handled, and swallowed, here again),
    to unwind where the main thread has gone on; anything else goes to the previous hook.
    """

    def unraisable(info) -> None:
        for signum, kind in UNWIND.items():
            if isinstance(info.exc_value, kind):
                signal.signal(signum, _on_signal)
                again = threading.Timer(0.05, os.kill, args=(os.getpid(), signum))
                again.daemon = True
                again.start()
                return
        hook(info)

    return unraisable


def _say(line: str) -> None:
    """Print one line on stderr (typer may not be loaded: a signal during the imports)."""
    with contextlib.suppress(OSError, ValueError):  # a closed or broken stderr
        print(line, file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    """Run the command line on ``argv``; return the exit status.

    User errors (:class:`~starsense.errors.StarsenseError`, a missing file) become one line on
    stderr and status 2. Usage errors (unknown option, bad type) are reported by typer itself,
    also with status 2. Ctrl-C and SIGTERM, from here on (the command's imports included),
    unwind the command and give one line and status 130 or 143.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 1 for a negative answer (a frame that does not solve), 2 for bad input,
        130 after Ctrl-C, 143 after SIGTERM.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    forget_signals()
    _written(forget=True)
    try:
        return _run(args)
    finally:
        forget_signals()  # a signal of this command says nothing about what the caller does next


def _run(args: list[str]) -> int:
    """Run the command ``args`` with the signals unwinding it; return its exit status."""
    try:
        with _signals_unwind():
            app = app_for(args)
            importlib.import_module("starsense.cli.helptext").reflow_app(app)
            app(args=args, prog_name="starsense")  # standalone mode: ends with SystemExit
    except Terminated:
        return _interrupted(signal.SIGTERM)
    except Interrupted:
        return _interrupted(signal.SIGINT)
    except BaseException as exc:
        # a signal came and something swallowed its unwind, or turned it into an error of its
        # own (pandas' compiled modules, interrupted while they import, say "partially
        # initialized module"; an optional import's ImportError reads "not installed"): the
        # signal ended the command, not what came after it
        received = signal_received()
        if received is not None:
            return _interrupted(received)
        return _ended_by(exc)
    return 0


def _ended_by(exc: BaseException) -> int:
    """Report how the command ended when no signal ended it; return its exit status."""
    if isinstance(exc, SystemExit):
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    if isinstance(exc, StarsenseError):
        _say(f"error: {exc}")
        return 2
    if isinstance(exc, FileNotFoundError):
        _say(f"error: file not found: {one_line(str(exc.filename), 300)}")
        return 2
    if isinstance(exc, OSError) and exc.filename is not None:
        # the system refused a path the user gave (a name too long, a permission) where no
        # reader said so in its own words: that path and the system's reason, on one line
        _say(f"error: {one_line(str(exc.filename), 300)}: {exc.strerror or exc}")
        return 2
    raise exc


def _interrupted(signum: int) -> int:
    """Say why the command ended after ``signum`` and what it wrote; return its exit status."""
    done = _written()
    said = "nothing written"
    if done:  # renamed into place, complete, before the signal (or held until complete)
        more = f" and {len(done) - 1} more" if len(done) > 1 else ""
        said = f"written before it, complete: {done[0]}{more}"
    if signum == signal.SIGTERM:
        _say(f"error: terminated (SIGTERM); {said}")
        return EXIT_TERMINATED
    _say(f"error: interrupted (Ctrl-C); {said}")
    return EXIT_INTERRUPTED


def _written(*, forget: bool = False) -> list:
    """Return the outputs put in place so far (none if the writing module was never loaded)."""
    files = sys.modules.get("starsense._io.files")
    return [] if files is None else files.written(forget=forget)


def console_main() -> None:  # pragma: no cover - thin wrapper for the console script
    """Run the command line on ``sys.argv`` and exit with its status (the ``starsense`` script).

    The process ends right after: its objects are frozen out of the collector first, so that
    the interpreter's last collection does not walk the hundreds of thousands the scientific
    modules hold (40-60 ms of a 0.6 s solve). Files are closed by their owners before this
    (the writers' context managers); the exit handlers still run.
    """
    code = main()
    gc.freeze()
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    console_main()
