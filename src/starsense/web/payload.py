"""A request's JSON body and its fields, checked: a malformed request is a 4xx, never a 500.

:func:`read_payload` turns the body into a JSON object or raises :class:`BadRequest` (400)
saying what is wrong with it (not UTF-8, not JSON, not an object, nested too deeply); the field
readers (:func:`number_field`, :func:`int_field`) raise
:class:`~starsense.errors.InputError` (the page's 422, shown beside the field) naming the field
and the value.
"""

from __future__ import annotations

import json
import math

from starlette.exceptions import HTTPException
from starlette.requests import Request

from starsense.errors import InputError

__all__ = ["BadRequest", "int_field", "number_field", "read_payload"]


class BadRequest(HTTPException):
    """The request's body is not a JSON object (status 400, the message on one line)."""

    def __init__(self, message: str) -> None:
        super().__init__(status_code=400, detail=message)


def _constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")


async def read_payload(request: Request) -> dict:
    """Return the request's body as a JSON object.

    Raises
    ------
    BadRequest
        Bytes that are not UTF-8 (the first bad byte and where), text that is not JSON
        (``NaN`` and ``Infinity`` included: not JSON), a value that is not an object, or one
        nested too deeply to read.
    """
    raw = await request.body()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise BadRequest(
            f"the request body is not UTF-8: byte 0x{raw[exc.start]:02x} at offset {exc.start}"
        ) from None
    try:
        value = json.loads(text, parse_constant=_constant)
    except json.JSONDecodeError as exc:
        raise BadRequest(
            f"the request body is not JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})"
        ) from None
    except ValueError as exc:  # NaN, Infinity
        raise BadRequest(f"the request body is not JSON: {exc}") from None
    except RecursionError:
        raise BadRequest("the request body is nested too deeply") from None
    if not isinstance(value, dict):
        raise BadRequest(
            f"the request body must be a JSON object, got {_json_kind(value)}"
        ) from None
    return value


def _json_kind(value: object) -> str:
    names = {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}
    return names.get(type(value), "a number")


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def number_field(payload: dict, name: str, *, default: float, lo: float, hi: float) -> float:
    """Return the number ``payload[name]`` (``default`` if absent), checked against [lo, hi].

    Raises
    ------
    InputError
        Not a number (a string, a boolean, null, an array), or out of range: naming the field
        and the value.
    """
    value = payload.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{name} = {_shown(value)}: must be a number")
    try:
        x = float(value)
    except OverflowError:  # an integer of hundreds of digits
        x = math.inf
    if not lo <= x <= hi:
        raise InputError(f"{name} = {_shown(value)} is out of range; must be in [{lo:g}, {hi:g}]")
    return x


def int_field(payload: dict, name: str, *, default: int, lo: int, hi: int) -> int:
    """Return the integer ``payload[name]`` (``default`` if absent), checked against [lo, hi].

    A number with a fractional part, a string, a boolean or null is refused.

    Raises
    ------
    InputError
        Naming the field and the value.
    """
    value = payload.get(name, default)
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError(f"{name} = {_shown(value)}: must be an integer")
    if not lo <= value <= hi:
        raise InputError(f"{name} = {_shown(value)} is out of range; must be in [{lo}, {hi}]")
    return value
