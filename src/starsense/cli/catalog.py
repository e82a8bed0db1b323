"""``starsense catalog import``, and the options the deep-catalogue commands share.

``hats:PATH_OR_URL`` catalogues (:mod:`starsense.scale`) are accepted by ``starsense limit sky``
and ``starsense availability static``, which then run on Dask (``--dask``). Thin: parse, call
the API, print. User errors are :class:`~starsense.errors.InputError`; the main app prints them
as one line and exits 2.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from starsense.cli.common import JsonOpt, emit

catalog_app = typer.Typer(
    help="Catalogues: turn a CSV / Parquet catalogue into HATS for the deep-catalogue commands.",
    no_args_is_help=True,
)

ScaleCatalogOpt = Annotated[
    str,
    typer.Option(
        "--catalog",
        help="hipparcos (bundled), bsc5:PATH, hip_main:PATH, tycho2:PATH, twomass:PATH, "
        "gaia:PATH, or hats:PATH_OR_URL (a HATS catalogue, processed on Dask; e.g. "
        "hats:https://data.lsdb.io/hats/gaia_dr3, hats:https://data.lsdb.io/hats/two_mass).",
    ),
]
DaskOpt = Annotated[
    str | None,
    typer.Option(
        "--dask",
        help="Dask cluster for hats: catalogues: local (default: this machine, one worker per "
        "CPU), local:N, or a scheduler address tcp://HOST:PORT.",
    ),
]


@contextlib.contextmanager
def partition_progress(enabled: bool) -> Iterator[Callable[[str, int, int], None] | None]:
    """A rich progress bar of partitions done, on stderr when it is a terminal and ``enabled``."""
    if not enabled or not sys.stderr.isatty():
        yield None
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("partitions"))  # fmt: skip
    with Progress(*columns, transient=True) as bar:
        tasks: dict[str, Any] = {}

        def update(label: str, done: int, total: int) -> None:
            if label not in tasks:
                tasks[label] = bar.add_task(label, total=total)
            bar.update(tasks[label], completed=done, total=total)

        yield update


@contextlib.contextmanager
def hats_session(catalog: str, dask: str | None, show_progress: bool) -> Iterator[tuple]:
    """(opened HATS catalogue, Dask client, progress callback) for a ``hats:`` command."""
    from starsense.scale import dask_client, open_hats

    cat = open_hats(catalog)
    with dask_client(dask) as client, partition_progress(show_progress) as progress:
        yield cat, client, progress


def check_dask_option(catalog: str, dask: str | None) -> bool:
    """True for a ``hats:`` catalogue; --dask with any other catalogue is an error."""
    from starsense.errors import InputError
    from starsense.scale.hats import is_hats_spec

    is_hats = is_hats_spec(catalog)
    if dask is not None and not is_hats:
        raise InputError(
            "--dask runs hats: catalogues on a cluster; with --catalog "
            f"{catalog!r} the analysis runs in memory (drop --dask or use --catalog hats:...)"
        )
    return is_hats


@catalog_app.command("import")
def catalog_import(
    input_path: Annotated[Path, typer.Argument(help="CSV (.csv, .csv.gz) or Parquet catalogue.")],
    output: Annotated[Path, typer.Argument(help="HATS catalogue directory to create.")],
    ra_column: Annotated[
        str, typer.Option("--ra-column", help="Right ascension column, ICRS degrees.")
    ] = "ra",
    dec_column: Annotated[
        str, typer.Option("--dec-column", help="Declination column, ICRS degrees.")
    ] = "dec",
    pixel_threshold: Annotated[
        int, typer.Option("--pixel-threshold", help="Most rows per HEALPix partition.")
    ] = 1_000_000,
    dask: DaskOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Turn a CSV or Parquet catalogue into a HATS catalogue (hats-import), atomically.

    Columns keep their names: Gaia archive names (phot_g_mean_mag, bp_rp ...), IRSA 2MASS names
    (j_m, h_m, k_m) or band names (V, B-V, G, J ...) are recognised by the deep-catalogue
    commands.
    """
    from starsense.scale import dask_client, import_catalog, open_hats

    with dask_client(dask) as client:
        out = import_catalog(
            input_path, output, ra_column=ra_column, dec_column=dec_column,
            pixel_threshold=pixel_threshold, client=client,
            progress=not as_json and sys.stderr.isatty(),
        )  # fmt: skip
    cat = open_hats(str(out))
    payload = {
        "output": str(out),
        "name": cat.name,
        "n_rows": cat.n_rows,
        "n_partitions": cat.n_partitions,
        "columns": list(cat.columns),
    }
    emit(payload, as_json, [
        f"HATS catalogue {out}: {cat.n_rows} rows in {cat.n_partitions} partitions",
        f"  columns: {', '.join(cat.columns)}",
        f"  use it with --catalog hats:{out}",
    ])  # fmt: skip
