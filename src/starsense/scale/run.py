"""Run a per-partition task over a HATS catalogue on a Dask cluster and reduce the results.

The partition tasks are submitted at once; their results are combined on the workers in a tree
(fan-in :data:`FAN_IN`), so only the final, small result comes back to this process. A progress
callback ``progress(label, done, total)`` is called as partitions finish.
"""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Callable, Iterator
from typing import Any

from starsense.scale._deps import quiet_third_party_warnings, require
from starsense.scale.cluster import dask_client
from starsense.scale.errors import CatalogUnavailableError
from starsense.scale.hats import ColumnPlan, HatsCatalog

#: partial results combined per reduction task
FAN_IN = 16

Progress = Callable[[str, int, int], None]


@contextlib.contextmanager
def client_or_local(client: Any | None) -> Iterator[Any]:
    """Yield the given client, or an in-process local cluster for the duration."""
    if client is not None:
        yield client
        return
    with dask_client("local", processes=False) as local:
        yield local


def run_partitions(
    client: Any,
    catalog: HatsCatalog,
    *,
    plan: ColumnPlan,
    kernel: Callable[..., Any],
    kernel_args: dict[str, Any],
    combine: Callable[..., Any],
    label: str,
    progress: Progress | None = None,
) -> Any:
    """``combine`` of ``kernel(partition, plan, **kernel_args)`` over the partitions of ``catalog``.

    Raises
    ------
    CatalogUnavailableError
        A partition cannot be read (file vanished, network error).
    """
    (dask,) = require("dask")
    (distributed,) = require("distributed")
    client.run(quiet_third_party_warnings)  # every worker (process) ignores the same warnings
    parts = catalog.partitions(plan.columns)
    if not parts:
        raise CatalogUnavailableError(f"HATS catalogue {catalog.location} has no partitions")
    # large arguments (attitudes, bin edges) go to the workers once, not once per task
    # (hash=False: a fresh key each run, for the reason given below)
    shipped = {
        name: client.scatter(a, broadcast=True, hash=False) if _nbytes(a) > 100_000 else a
        for name, a in kernel_args.items()
    }
    # lsdb names the partition reads by content: the same columns read twice give the same keys,
    # and a second run submitted while the scheduler still releases the first one's keys fails
    # with "lost dependencies". Fresh keys per run avoid that race.
    from dask.graph_manipulation import clone

    seed = uuid.uuid4().hex
    parts = list(clone(*parts, seed=seed)) if len(parts) > 1 else [clone(parts[0], seed=seed)]
    tasks = [dask.delayed(kernel, pure=False)(p, plan, **shipped) for p in parts]
    futures = client.compute(tasks)
    level = list(futures)
    while len(level) > 1:
        level = [
            client.submit(combine, *level[i : i + FAN_IN], pure=False)
            for i in range(0, len(level), FAN_IN)
        ]
    try:
        if progress is not None:
            progress(label, 0, len(futures))
            for done, _ in enumerate(distributed.as_completed(futures), 1):
                progress(label, done, len(futures))
        result = level[0].result()
    except BaseException as exc:
        client.cancel(level[0], force=True)  # and, through it, the partition tasks still queued
        if isinstance(exc, OSError | EOFError):
            raise CatalogUnavailableError(
                f"reading HATS catalogue {catalog.location} failed: {type(exc).__name__}: {exc}"
            ) from None
        raise
    return combine(result) if len(futures) == 1 else result


def _nbytes(obj: Any) -> int:
    nbytes = getattr(obj, "nbytes", None)
    if nbytes is not None:
        return int(nbytes)
    as_matrix = getattr(obj, "as_matrix", None)  # scipy Rotation
    if callable(as_matrix):
        return int(as_matrix().nbytes)
    return 0
