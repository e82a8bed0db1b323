"""``starsense catalog import``, and the options the deep-catalogue commands share.

``hats:PATH_OR_URL`` catalogues (:mod:`starsense.scale`) are accepted by ``starsense limit sky``
and ``starsense availability static``, which then run on Dask (``--dask``). Thin: parse, call
the API, print. User errors are :class:`~starsense.errors.InputError`; the main app prints them
as one line and exits 2.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer

from starsense.cli.common import DaskOpt, JsonOpt, emit, option_int, progress_bar
from starsense.errors import InputError
from starsense.scale import dask_client, import_catalog, open_hats
from starsense.scale.cluster import check_scheduler
from starsense.scale.errors import MissingColumnsError
from starsense.scale.importer import check_import
from starsense.scale.location import check_url, is_hats_spec

catalog_app = typer.Typer(
    help="Catalogues: turn a CSV / Parquet catalogue into HATS for the deep-catalogue commands.",
    no_args_is_help=True,
)


@contextlib.contextmanager
def hats_session(catalog: str, dask: str | None, show_progress: bool) -> Iterator[tuple]:
    """Yield (opened HATS catalogue, Dask client, progress callback) for a ``hats:`` command.

    The callback is None when the bar of partitions done is hidden (``show_progress`` false, or
    stderr not a terminal).
    """
    check_scheduler(dask)  # a malformed or refused --dask fails before the catalogue is opened
    check_url(catalog)  # a refused URL too: both before lsdb is imported

    cat = open_hats(catalog)
    with dask_client(dask) as client, progress_bar(show_progress, unit="partitions") as bar:
        yield cat, client, bar.callback


def check_dask_option(catalog: str, dask: str | None) -> bool:
    """Return True for a ``hats:`` catalogue; --dask with any other catalogue is an error."""
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
    # a partition is read whole by one worker: 10**23 rows went on to hats-import unchecked
    option_int(pixel_threshold, "--pixel-threshold", 1, 1_000_000_000)

    check_scheduler(dask)  # a bad --dask, a bad input or output: before any worker starts
    try:
        check_import(
            input_path,
            output,
            ra_column=ra_column,
            dec_column=dec_column,
            pixel_threshold=pixel_threshold,
        )
    except MissingColumnsError as exc:  # the library names parameters; say the options
        text = str(exc).replace("ra_column / dec_column", "--ra-column / --dec-column")
        raise MissingColumnsError(text) from None
    with dask_client(dask) as client:
        out = import_catalog(
            input_path,
            output,
            ra_column=ra_column,
            dec_column=dec_column,
            pixel_threshold=pixel_threshold,
            client=client,
            progress=not as_json and sys.stderr.isatty(),
        )
    cat = open_hats(str(out))
    payload = {
        "output": str(out),
        "name": cat.name,
        "n_rows": cat.n_rows,
        "n_partitions": cat.n_partitions,
        "columns": list(cat.columns),
    }
    emit(
        payload,
        as_json,
        [
            f"HATS catalogue {out}: {cat.n_rows} rows in {cat.n_partitions} partitions",
            f"  columns: {', '.join(cat.columns)}",
            f"  use it with --catalog hats:{out}",
        ],
    )
