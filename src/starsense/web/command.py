"""``starsense design``: start the design page's server and open it in the browser."""

from __future__ import annotations

import importlib
import threading
import webbrowser
from typing import Annotated

import typer

from starsense.cli.common import option_int
from starsense.errors import InputError

__all__ = ["design"]


def design(
    *,
    sensor: Annotated[
        str, typer.Option("--sensor", help="Base design: a preset (st16) or a sensor TOML file.")
    ] = "st16",
    port: Annotated[int, typer.Option("--port", help="Local port of the page.")] = 8765,
    catalog: Annotated[
        str, typer.Option("--catalog", help="Catalogue (default: bundled Hipparcos).")
    ] = "hipparcos",
    open_browser: Annotated[
        bool, typer.Option("--open/--no-open", help="Open the page in the browser.")
    ] = True,
) -> None:
    """Edit a sensor in the browser and see its datasheet's predictions update live."""
    option_int(port, "--port", 1, 65535)
    try:
        uvicorn = importlib.import_module("uvicorn")
        create_app = importlib.import_module("starsense.web.app").create_app
    except ImportError as exc:
        raise InputError(
            f"the design page needs the web extra ({exc.name} is missing): "
            "pip install 'starsense[web]'"
        ) from None
    app = create_app(sensor, catalog)
    url = f"http://127.0.0.1:{port}/"
    typer.echo(f"starsense design: {url} (Ctrl-C to stop)")
    if open_browser:
        threading.Timer(1.0, webbrowser.open, args=(url,)).start()
    uvicorn.run(app, host="127.0.0.1", port=port, log_level="warning")
