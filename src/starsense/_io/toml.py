"""TOML text to a document, with every failure one line naming the source.

:func:`tomllib.loads` recurses once per nested array or inline table, so a file of 50,000
nested brackets raises RecursionError (a traceback), and it refuses a UTF-8 byte-order mark
(which Windows editors write). Both are handled here, once, for every TOML the package reads.
"""

from __future__ import annotations

import tomllib

from starsense.errors import InputError

__all__ = ["BOM", "parse_toml", "strip_bom"]

#: the UTF-8 byte-order mark, decoded
BOM = "\ufeff"


def strip_bom(text: str) -> str:
    """Return ``text`` without a leading UTF-8 byte-order mark (an editor's, not content)."""
    return text[1:] if text.startswith(BOM) else text


def parse_toml(text: str, source: str, *, invalid: str = "invalid TOML") -> dict:
    """Return the TOML document of ``text``.

    Parameters
    ----------
    text : str
        The file's content (a leading byte-order mark is ignored).
    source : str
        The file or preset, for the messages.
    invalid : str
        How a message calls a syntax error ("invalid TOML").

    Returns
    -------
    dict

    Raises
    ------
    InputError
        One line: ``source``, the syntax error and where (line, column), or the nesting too
        deep to read.
    """
    try:
        return tomllib.loads(strip_bom(text))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: {invalid}: {exc}") from None
    except RecursionError:
        raise InputError(
            f"{source}: {invalid}: arrays or tables nested too deeply to read "
            "(thousands of levels); a sensor file needs a few"
        ) from None
