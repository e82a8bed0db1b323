"""The analyses over catalogues too big for memory, on a cluster.

HATS catalogues are read by ``lsdb`` on ``dask.distributed`` (``pip install 'starsense[scale]'``).

* :func:`open_hats` — a HATS catalogue from a path or URL (:data:`PUBLISHED_HATS`: Gaia DR3,
  2MASS);
* :func:`sky_limit`, :func:`fov_limit`, :func:`brightest_curve` — the attitude-accuracy limit
  (Fialho & Mortari 2019);
* :func:`star_counts`, :func:`static_availability` — stars in the field per boresight and
  availability (Dzamba & Enright 2014);
* :func:`dask_client` — an in-process cluster, or any scheduler by address;
* :func:`import_catalog` — a user's CSV / Parquet catalogue to HATS (hats-import).

Per-partition work calls the in-memory kernels (:mod:`starsense.scale.kernels`); the results
equal the in-memory ones to the rounding of sums. Importing this package does not import lsdb
or dask; every function does, and raises :class:`ScaleNotInstalledError` if they are missing.
"""

from __future__ import annotations

import importlib
from typing import Any

from starsense.scale.errors import (
    CatalogUnavailableError,
    MissingColumnsError,
    ScaleNotInstalledError,
    SchedulerUnreachableError,
)

_LAZY = {
    "open_hats": "starsense.scale.hats",
    "HatsCatalog": "starsense.scale.hats",
    "PUBLISHED_HATS": "starsense.scale.location",
    "is_hats_spec": "starsense.scale.location",
    "sky_limit": "starsense.scale.limits",
    "fov_limit": "starsense.scale.limits",
    "brightest_curve": "starsense.scale.limits",
    "star_counts": "starsense.scale.availability",
    "static_availability": "starsense.scale.availability",
    "dask_client": "starsense.scale.cluster",
    "import_catalog": "starsense.scale.importer",
}

__all__ = [
    "CatalogUnavailableError",
    "MissingColumnsError",
    "ScaleNotInstalledError",
    "SchedulerUnreachableError",
    *_LAZY,
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'starsense.scale' has no attribute {name!r}")
