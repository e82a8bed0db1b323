"""The command listings (``starsense --help``, ``starsense limit``), read without importing.

A listing shows each command's name and help. Importing every command module for it would load
most of the package (SciPy, matplotlib, astropy: over a second), so the listing is read from
the modules' source instead (:mod:`ast`): a command function's docstring, a group's
``typer.Typer(help=...)`` and the functions under its ``@group.command(...)`` decorators. The
app built here has those names and helps on empty stand-ins; it only lists, and typer prints the
same text as for the real commands. Whatever it cannot read plainly (a help that is not a
literal, a command registered some other way) returns None, and the caller imports the real
modules (:func:`starsense.cli.app.build_app`).

Parsing the modules (~5,000 lines) is most of a listing's own time, so what it reads is kept in
a small JSON file in the cache directory (``$STARSENSE_CACHE_DIR/cli`` or the user cache
directory), each entry with the size and modification time of the module it was read from: an
edited module is read again, and a cache that cannot be read or written is only slower.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import importlib.util
import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import typer

from starsense.errors import StarsenseError

__all__ = ["GroupListing", "command_help", "group_listing", "listing_app"]


@dataclass(frozen=True)
class GroupListing:
    """A command group as its module's source declares it.

    Attributes
    ----------
    options : dict
        The literal keyword arguments of its ``typer.Typer(...)`` (``help``, ``no_args_is_help``).
    commands : tuple of (str, str or None)
        Its commands in the order of registration: name and docstring.
    callback : bool
        It has a ``@group.callback()`` without options (then ``callback_doc`` is its docstring).
    callback_doc : str or None
        The callback's docstring.
    """

    options: dict
    commands: tuple[tuple[str, str | None], ...]
    callback: bool = False
    callback_doc: str | None = None


@functools.cache
def _tree(module: str) -> ast.Module | None:
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
        return None
    return ast.parse(Path(spec.origin).read_text(encoding="utf-8"))


def _function(tree: ast.Module, name: str) -> ast.FunctionDef | None:
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == name:
            return node
    return None


#: the layout of the cache file (bump when what is stored changes)
_CACHE_FORMAT = 1
_CACHE_NAME = "cli-listing.json"


def _cache_file() -> Path:
    env = os.environ.get("STARSENSE_CACHE_DIR")
    if env:
        return Path(env).expanduser() / "cli" / _CACHE_NAME
    import platformdirs  # noqa: PLC0415 - only where no cache directory is set

    return Path(platformdirs.user_cache_dir("starsense")) / "cli" / _CACHE_NAME


@functools.cache
def _cache() -> dict:
    """Return the cache file's entries (empty: missing, unreadable, another format)."""
    try:
        data = json.loads(_cache_file().read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    ok = isinstance(data, dict) and data.get("format") == _CACHE_FORMAT
    return dict(data.get("entries", {})) if ok and isinstance(data.get("entries"), dict) else {}


_unsaved: list[bool] = []  # an entry was added since the file was read


def _stamp(module: str) -> list | None:
    """Return the module's file, size and modification time (None: not a source file)."""
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
        return None
    st = os.stat(spec.origin)
    return [spec.origin, st.st_size, st.st_mtime_ns]


def _remembered(kind: str, module: str, attribute: str, read: Callable[[], object]) -> object:
    """Return ``read()`` of a module, from the cache while the module's file is unchanged."""
    stamp = _stamp(module)
    key = f"{kind}:{module}:{attribute}"
    entry = _cache().get(key)
    if stamp is not None and isinstance(entry, dict) and entry.get("stamp") == stamp:
        return entry.get("value")
    value = read()
    if stamp is not None:
        _cache()[key] = {"stamp": stamp, "value": value}
        _unsaved.append(True)
    return value


def save_cache() -> None:
    """Write the entries read since the cache file was read (nothing said if it cannot be)."""
    if not _unsaved:
        return
    from starsense._io.files import atomic_write  # noqa: PLC0415 - only when there is news

    path = _cache_file()
    with contextlib.suppress(OSError, StarsenseError):
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_write(path, output=False) as fh:
            json.dump({"format": _CACHE_FORMAT, "entries": _cache()}, fh)
        _unsaved.clear()


def command_help(module: str, attribute: str) -> str | None:
    """Return the docstring of the command function ``module.attribute``, read from its source.

    Parameters
    ----------
    module : str
        The module's dotted name.
    attribute : str
        The function's name.

    Returns
    -------
    str or None
        The docstring as Python stores it (``__doc__``); None when there is no such function.
    """
    return _remembered("help", module, attribute, lambda: _read_help(module, attribute))


def _read_help(module: str, attribute: str) -> str | None:
    tree = _tree(module)
    node = None if tree is None else _function(tree, attribute)
    return None if node is None else ast.get_docstring(node, clean=False)


def _typer_options(tree: ast.Module, attribute: str) -> dict | None:
    """Return the literal keyword arguments of ``attribute = typer.Typer(...)``, else None."""
    for node in tree.body:
        if (
            isinstance(node, ast.Assign)
            and [ast.unparse(t) for t in node.targets] == [attribute]
            and isinstance(node.value, ast.Call)
            and ast.unparse(node.value.func) == "typer.Typer"
            and not node.value.args
        ):
            try:
                return {k.arg: ast.literal_eval(k.value) for k in node.value.keywords}
            except ValueError:  # a help that is not a literal
                return None
    return None


def _command_name(decorator: ast.expr, attribute: str, function: str) -> str | None:
    """Return the name a ``@attribute.command(...)`` decorator gives (None: another one)."""
    if not (
        isinstance(decorator, ast.Call) and ast.unparse(decorator.func) == f"{attribute}.command"
    ):
        return None
    if decorator.keywords or len(decorator.args) > 1:
        raise ValueError("a command option the listing does not read")
    if decorator.args:
        return ast.literal_eval(decorator.args[0])
    return function.lower().replace("_", "-")  # typer's name for a function


def group_listing(module: str, attribute: str) -> GroupListing | None:
    """Return the group ``module.attribute`` (a :class:`typer.Typer`) as its source declares it.

    Parameters
    ----------
    module : str
        The module's dotted name.
    attribute : str
        The group's name in the module.

    Returns
    -------
    GroupListing or None
        None when the source does not declare it plainly: then only importing tells.
    """
    got = _remembered("group", module, attribute, lambda: _read_group(module, attribute))
    if got is None:
        return None
    options, commands, callback, callback_doc = got
    return GroupListing(options, tuple(tuple(c) for c in commands), callback, callback_doc)


def _read_group(module: str, attribute: str) -> list | None:
    """:func:`group_listing` read from the source, as JSON values (None: not plainly)."""
    tree = _tree(module)
    options = None if tree is None else _typer_options(tree, attribute)
    if options is None:
        return None
    # every use of the group in its module: only the decorators read below may register on it
    uses = [
        n.attr
        for n in ast.walk(tree)
        if isinstance(n, ast.Attribute) and ast.unparse(n.value) == attribute
    ]
    commands, callbacks = [], []
    for node in tree.body:
        if not isinstance(node, ast.FunctionDef):
            continue
        if f"{attribute}.callback()" in [ast.unparse(d) for d in node.decorator_list]:
            if ast.unparse(node.args) or len(node.decorator_list) > 1:
                return None  # a callback with options
            callbacks.append(ast.get_docstring(node, clean=False))
            continue
        try:
            names = [
                n for d in node.decorator_list if (n := _command_name(d, attribute, node.name))
            ]
        except ValueError:
            return None
        commands += [(name, ast.get_docstring(node, clean=False)) for name in names]
    if sorted(uses) != sorted(["command"] * len(commands) + ["callback"] * len(callbacks)):
        return None  # registered some other way, or a sub-group: only importing tells
    if len(callbacks) > 1:
        return None
    return [options, commands, bool(callbacks), next(iter(callbacks), None)]


def _stand_in(doc: str | None) -> Callable[[], None]:
    def command() -> None:
        pass  # never run: a listing only shows names and helps

    command.__doc__ = doc
    return command


def listing_app(
    app: typer.Typer,
    commands: Mapping[str, tuple[str, str]],
    subcommands: Mapping[str, Mapping[str, tuple[str, str]]],
) -> typer.Typer | None:
    """Register stand-ins of ``commands`` on ``app`` for a listing; None if one cannot be read.

    Parameters
    ----------
    app : typer.Typer
        The top-level app, without commands.
    commands : mapping
        Command name -> (module, attribute): a function or a group
        (:data:`starsense.cli.app.COMMANDS`).
    subcommands : mapping
        Group name -> {command name: (module, function)}: a group's commands kept in other
        modules (:data:`starsense.cli.app.SUBCOMMANDS`), listed after its own.

    Returns
    -------
    typer.Typer or None
        ``app``, or None when some command's help cannot be read from its source.
    """
    for name, (module, attribute) in commands.items():
        group = group_listing(module, attribute)
        if group is not None:
            sub = typer.Typer(**group.options)
            if group.callback:
                sub.callback()(_stand_in(group.callback_doc))
            extra = [(n, command_help(*where)) for n, where in subcommands.get(name, {}).items()]
            for sub_name, doc in [*group.commands, *extra]:
                if doc is None:
                    return None
                sub.command(sub_name)(_stand_in(doc))
            app.add_typer(sub, name=name)
            continue
        doc = command_help(module, attribute)
        if doc is None:
            return None
        app.command(name)(_stand_in(doc))
    save_cache()
    return app
