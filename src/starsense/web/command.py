"""``starsense design``: start the design page's server and open it in the browser."""

from __future__ import annotations

import contextlib
import gc
import importlib
import signal
import threading
import webbrowser
from typing import Annotated

import typer

from starsense.cli.common import option_int
from starsense.errors import InputError

__all__ = ["HOST", "STOP_GRACE_S", "design"]

#: the address the page listens on: this machine only
HOST = "127.0.0.1"
#: how long a stopping server (SIGTERM, Ctrl-C) lets requests in progress finish, s; then they
#: are cancelled (a prediction in progress is not waited for, see starsense.web.app)
STOP_GRACE_S = 0.5


def design(
    *,
    sensor: Annotated[
        str, typer.Option("--sensor", help="Base design: a preset (st16) or a sensor TOML file.")
    ] = "st16",
    port: Annotated[int, typer.Option("--port", help="Local port of the page.")] = 8765,
    catalog: Annotated[
        str, typer.Option("--catalog", help="Catalogue (default: bundled Hipparcos).")
    ] = "hipparcos",
    n_orientations: Annotated[
        int,
        typer.Option("--n-orientations", help="Boresights of the predictions' sky statistics."),
    ] = 2000,
    slew_trials: Annotated[
        int, typer.Option("--slew-trials", help="Renders per point of the slew tolerance.")
    ] = 20,
    open_browser: Annotated[
        bool, typer.Option("--open/--no-open", help="Open the page in the browser.")
    ] = True,
) -> None:
    """Edit a sensor in the browser and see its datasheet's predictions update live."""
    option_int(port, "--port", 1, 65535)
    option_int(n_orientations, "--n-orientations", 1, 100_000)
    option_int(slew_trials, "--slew-trials", 1, 1000)
    try:
        uvicorn = importlib.import_module("uvicorn")
        create_app = importlib.import_module("starsense.web.app").create_app
    except ImportError as exc:
        raise InputError(
            f"the design page needs the web extra ({exc.name} is missing): "
            "pip install 'starsense[web]'"
        ) from None
    app = create_app(
        sensor,
        catalog,
        host=HOST,
        port=port,
        n_orientations=n_orientations,
        n_slew_trials=slew_trials,
    )
    url = f"http://{HOST}:{port}/"
    typer.echo(f"starsense design: {url} (Ctrl-C to stop)")
    if open_browser:
        opener = threading.Timer(1.0, webbrowser.open, args=(url,))
        opener.daemon = True  # a server stopped at once does not wait for it
        opener.start()
    config = uvicorn.Config(
        app, host=HOST, port=port, log_level="warning", timeout_graceful_shutdown=STOP_GRACE_S
    )
    try:
        _serve(uvicorn, config)  # SIGTERM: raised again once it has stopped
    finally:
        # the process ends now: spare its exit a garbage collection of the whole heap (over a
        # second with the catalogue and the prediction's modules loaded)
        gc.freeze()


def _serve(uvicorn, config) -> None:
    """Run the server until a signal; raise that signal again once it has stopped.

    A SIGINT or SIGTERM is held from here until the server listens for its own: one arriving
    while the event loop was being made unwound it half made (an "Exception ignored" traceback
    from the loop, a coroutine never awaited). Held, it stops the server as soon as it starts.
    """
    held: list[int] = []

    class Server(uvicorn.Server):
        @contextlib.contextmanager
        def capture_signals(self):
            with super().capture_signals():
                for signum in held:  # came while the loop was made: stop at once
                    self.handle_exit(signum, None)
                held.clear()
                yield

    old = {}
    if threading.current_thread() is threading.main_thread():
        old = {s: signal.signal(s, lambda n, f: held.append(n)) for s in _HELD}
    try:
        Server(config).run()
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(held):  # the server's own, raised again when it stopped
            signal.raise_signal(s)


_HELD = (signal.SIGINT, signal.SIGTERM)
