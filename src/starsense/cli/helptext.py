r"""Help text that wraps at the terminal's width, never at the docstring's line breaks.

typer (rich mode) joins the lines of a command's first help paragraph but keeps the single
line breaks of the others, and rich then wraps each of those lines at the terminal's width: at
80 columns a docstring written to 99 prints "the database is" / "loaded once" on two lines.
:func:`reflow_app` joins the lines of every prose paragraph of every command's and group's help
before typer reads it, so rich wraps whole paragraphs. A paragraph that starts with ``\b``
(click's "keep as is" mark), or whose lines after the first start with a list mark or an
indent, keeps its line breaks.
"""

from __future__ import annotations

import inspect
import re

__all__ = ["reflow", "reflow_app"]

#: a line that starts a list item or is indented: its paragraph keeps its line breaks
_BLOCK_LINE = re.compile(r"^(\s+|[-*+] |\d+[.)] )")


def reflow(text: str | None) -> str | None:
    r"""Return ``text`` with each prose paragraph on one line (blank lines between them kept).

    Parameters
    ----------
    text : str or None
        A docstring or help string (indented as in the source, or not).

    Returns
    -------
    str or None
        The help, dedented; None for None. Everything from a line holding only ``\f`` on (what
        click hides from the help) is kept as it was.
    """
    if text is None:
        return None
    shown, mark, hidden = inspect.cleandoc(text).partition("\n\f")
    paragraphs = []
    for para in shown.split("\n\n"):
        lines = para.split("\n")
        block = para.startswith("\b") or any(_BLOCK_LINE.match(line) for line in lines[1:])
        paragraphs.append(para if block else " ".join(line.strip() for line in lines))
    return "\n\n".join(paragraphs) + mark + hidden


def reflow_app(app) -> None:
    """Reflow the help of every command, group and callback of a typer app, in place.

    Parameters
    ----------
    app : typer.Typer
        The app (its groups are walked too). A command's help is its ``help=`` or, when none
        was given, its function's docstring; the function itself is left as it is.
    """
    info = app.info
    if isinstance(info.help, str):
        info.help = reflow(info.help)
    callback = app.registered_callback  # only a help given: its docstring ranks below info's
    if callback is not None and isinstance(callback.help, str):
        callback.help = reflow(callback.help)
    for command in app.registered_commands:
        command.help = reflow(command.help or (command.callback and command.callback.__doc__))
    for group in app.registered_groups:
        if isinstance(group.help, str):
            group.help = reflow(group.help)
        if group.typer_instance is not None:
            reflow_app(group.typer_instance)
