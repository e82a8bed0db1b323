"""Errors of the distributed path.

Each is a :class:`~starsense.errors.InputError`, so the CLI prints one line and exits 2.
"""

from __future__ import annotations

from starsense.errors import InputError


class ScaleNotInstalledError(InputError):
    """lsdb, hats, hats-import or dask.distributed is missing: ``pip install starsense[scale]``."""


class CatalogUnavailableError(InputError):
    """A HATS catalogue path or URL does not exist, cannot be reached, or is not HATS."""


class MissingColumnsError(InputError):
    """A HATS catalogue lacks a column the analysis needs (position, magnitude or colour)."""


class SchedulerUnreachableError(InputError):
    """No Dask scheduler answers at the given address within the connect timeout."""
