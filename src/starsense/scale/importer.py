"""``starsense catalog import``: a CSV or Parquet catalogue to a HATS catalogue (hats-import).

The catalogue is written into a temporary directory next to the output and renamed into place
only when hats-import has finished, so an interrupted or failed import leaves no half-written
catalogue behind. The columns are kept as they are; :mod:`starsense.scale.hats` finds the
positions, magnitudes and colours by name.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from starsense._io import check_output, deferred_signals, note_written, sweep_stale, temp_prefix
from starsense._validate import check_int, show
from starsense.catalog._parse import locate_delimited_error
from starsense.errors import InputError, unwind_if_signalled
from starsense.scale._deps import quiet_third_party_warnings, require
from starsense.scale.errors import CatalogUnavailableError, MissingColumnsError
from starsense.scale.run import client_or_local

_FORMATS = {".csv": "csv", ".csv.gz": "csv", ".parquet": "parquet", ".pq": "parquet"}


def input_format(path: Path) -> str:
    """``"csv"`` or ``"parquet"`` from the file name."""
    name = path.name.lower()
    for suffix, fmt in _FORMATS.items():
        if name.endswith(suffix):
            return fmt
    raise InputError(
        f"cannot tell the format of {path} from its name; expected one of {', '.join(_FORMATS)}"
    )


def input_columns(path: Path, fmt: str) -> list[str]:
    """Column names of the input (Parquet schema or CSV header)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    try:
        if fmt == "parquet":
            return list(pq.read_schema(path).names)
        with pcsv.open_csv(path) as reader:
            return list(reader.schema.names)
    except (pa.ArrowException, OSError) as exc:
        raise CatalogUnavailableError(f"cannot read {path}: {exc}") from None
    except UnicodeDecodeError:  # a header that is not text (a binary file named .csv)
        raise CatalogUnavailableError(f"cannot read {path}: its header is not UTF-8 text") from None


def _check_batch(batch: Any, src: Path, fmt: str, columns: tuple[str, str], offset: int) -> int:
    """Refuse a missing, NaN, infinite or out-of-range position in one batch; return its rows.

    A NaN position imported as is lands in no HEALPix pixel a query reaches: the star would be
    silently lost (or the import fail deep in a worker).
    """
    for col, limit in zip(columns, (360.0, 90.0), strict=True):
        values = batch.column(col).to_numpy(zero_copy_only=False).astype(np.float64)
        bad = ~np.isfinite(values) | (np.abs(values) > limit)
        if bad.any():
            i = int(np.argmax(bad))
            where = f"line {offset + i + 2}" if fmt == "csv" else f"row {offset + i + 1}"
            missing = batch.column(col)[i].as_py() is None  # CSV: empty, "nan", "NA", ...
            shown = "a missing value (empty or NaN)" if missing else show(values[i])
            raise InputError(
                f"cannot import {src}: {where}, column {col}: {shown} is not a position "
                f"(a finite number within +-{limit:g} deg); {int(bad.sum())} such in this "
                "block; fix or drop those rows"
            )
    return batch.num_rows


def _check_positions(src: Path, fmt: str, ra: str, dec: str) -> None:
    """Read the position columns once (streamed): name a bad or NaN position before any worker."""
    import pyarrow as pa
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    offset = 0
    try:
        if fmt == "parquet":
            for batch in pq.ParquetFile(src).iter_batches(columns=[ra, dec]):
                offset += _check_batch(batch, src, fmt, (ra, dec), offset)
        else:
            convert = pcsv.ConvertOptions(
                include_columns=[ra, dec], column_types={ra: pa.float64(), dec: pa.float64()}
            )
            with pcsv.open_csv(src, convert_options=convert) as reader:
                for batch in reader:
                    offset += _check_batch(batch, src, fmt, (ra, dec), offset)
    except (pa.ArrowInvalid, OSError) as exc:
        detail = _failure_detail(src, fmt, ra, dec, " ".join(str(exc).split()))
        raise InputError(f"cannot import {src}: {detail}") from None
    if offset == 0:  # hats-import would fail on it with a FileNotFoundError naming no file
        header = " (a header only)" if fmt == "csv" else ""
        raise InputError(f"cannot import {src}: the file has no rows{header}")


@contextlib.contextmanager
def _collect_worker_prints(client: Any) -> Iterator[list[str]]:
    """Yield a list collecting what tasks print through Dask, instead of the client's stdout.

    hats-import prints each failed task (worker address, message) that way; the command's
    output stays clean and the error names the cause in one line.
    """
    printed: list[str] = []

    def collect(event: Any) -> None:
        msg = event[1] if isinstance(event, tuple) and len(event) == 2 else event
        args = msg.get("args", ()) if isinstance(msg, dict) else (msg,)
        printed.append(" ".join(str(a) for a in args))

    handlers = getattr(client, "_event_handlers", {})
    previous = handlers.get("print") if isinstance(handlers, dict) else None
    client.subscribe_topic("print", collect)
    try:
        yield printed
    finally:
        if previous is not None:
            client.subscribe_topic("print", previous)
        else:
            client.unsubscribe_topic("print")


def _failure_detail(src: Path, fmt: str, ra: str, dec: str, printed: str) -> str:
    """Say why hats-import failed: a CSV's first bad position, else its workers' last message."""
    if fmt == "csv":
        found = locate_delimited_error(
            src,
            delimiter=",",
            names=None,
            skip_lines=0,
            numeric={ra: float, dec: float},
            required=(ra, dec),
            null_values=("",),
            quoting=True,
        )
        if found is not None:
            return f"line {found.line}, column {found.field}: {found.detail}"
    lines = [ln.strip() for ln in printed.splitlines() if ln.strip()]
    return lines[-1] if lines else "a hats-import task failed"


def check_import(
    input_path: str | Path,
    output: str | Path,
    *,
    ra_column: str = "ra",
    dec_column: str = "dec",
    pixel_threshold: int = 1_000_000,
) -> tuple[Path, Path, str]:
    """Check an import before any worker starts; return (input, output, format).

    The input exists and its format is known, the output does not exist and its directory is
    writable, the position columns are there and (CSV) every position is a number.

    Raises
    ------
    InputError
        Naming the file, and for a bad position the line, column and value.
    """
    src = Path(input_path).expanduser()
    if not src.is_file():
        raise CatalogUnavailableError(f"input catalogue not found: {src}")
    dst = check_output(output, "output", directory=True)
    fmt = input_format(src)
    if dst.exists():
        raise InputError(f"output {dst} already exists; remove it or choose another name")
    check_int(pixel_threshold, "pixel_threshold", 1)
    columns = input_columns(src, fmt)
    missing = [c for c in (ra_column, dec_column) if c not in columns]
    if missing:
        raise MissingColumnsError(
            f"{src}: position column(s) {', '.join(missing)} missing (columns: "
            f"{', '.join(columns)}); name them with ra_column / dec_column"
        )
    _check_positions(src, fmt, ra_column, dec_column)
    return src, dst, fmt


def import_catalog(
    input_path: str | Path,
    output: str | Path,
    *,
    ra_column: str = "ra",
    dec_column: str = "dec",
    pixel_threshold: int = 1_000_000,
    client: Any | None = None,
    progress: bool = False,
) -> Path:
    """Turn a CSV or Parquet file into a HATS catalogue at ``output`` (a new directory).

    Parameters
    ----------
    input_path : path
        ``.csv``, ``.csv.gz``, ``.parquet`` or ``.pq`` with a header naming the columns.
    output : path
        The catalogue directory to create (must not exist); its name is the catalogue's name.
    ra_column, dec_column : str
        ICRS position columns, degrees.
    pixel_threshold : int
        Most rows per HEALPix tile (hats-import's ``pixel_threshold``).
    client : distributed.Client or None
        Default: an in-process local cluster for the call.
    progress : bool
        Let hats-import draw its progress bars (stderr).

    Raises
    ------
    InputError
        Missing input, unknown format, existing output, missing position columns.
    """
    src, dst, fmt = check_import(
        input_path,
        output,
        ra_column=ra_column,
        dec_column=dec_column,
        pixel_threshold=pixel_threshold,
    )
    require("hats_import", "distributed")
    from hats_import.catalog.arguments import ImportArguments
    from hats_import.pipeline import pipeline_with_client

    unwind_if_signalled()  # a signal its imports swallowed: no cluster is started for nothing

    dst.parent.mkdir(parents=True, exist_ok=True)
    sweep_stale(dst)  # what a killed import left beside the output
    work = Path(tempfile.mkdtemp(prefix=temp_prefix(dst), suffix=".tmp", dir=dst.parent))
    try:
        with warnings.catch_warnings():
            quiet_third_party_warnings()
            args = ImportArguments(
                output_path=work,
                output_artifact_name=dst.name,
                input_file_list=[src],
                file_reader=fmt,
                ra_column=ra_column,
                dec_column=dec_column,
                pixel_threshold=int(pixel_threshold),
                tmp_dir=work / "intermediate",
                resume=False,
                progress_bar=progress,
            )
            with client_or_local(client) as c, _collect_worker_prints(c) as printed:
                pipeline_with_client(args, c)
        shutil.rmtree(work / "intermediate", ignore_errors=True)
        with deferred_signals():  # never after a signal, even one a worker pool swallowed
            (work / dst.name).rename(dst)
            note_written(dst)
    except (ValueError, KeyError) as exc:
        raise InputError(f"hats-import could not import {src}: {exc}") from None
    except RuntimeError:  # "Some mapping stages failed. See above Exceptions."
        detail = _failure_detail(src, fmt, ra_column, dec_column, "\n".join(printed))
        raise InputError(f"hats-import could not import {src}: {detail}") from None
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return dst
