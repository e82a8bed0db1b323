"""Vectorised parsing helpers shared by the catalogue readers (private module).

The readers never build one Python object per star: a fixed-width text file is viewed as a
``(n_records, record_length)`` array of bytes, each field is a column slice of that array and
is converted in one call to Arrow's C++ number parser (delimited files go through
:mod:`pyarrow.csv`). Only when a conversion fails do we walk the offending column in Python,
to name the first bad line and field in a :class:`~starsense.errors.CatalogFormatError`.
"""

from __future__ import annotations

import csv
import gzip
import math
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from starsense._io import readable_file
from starsense.errors import CatalogFormatError

_SPACE = ord(" ")
_NEWLINE = ord("\n")
_PIPE = ord("|")

# Bytes allowed in a numeric field. Anything else (letters, 'nan', '_', tabs) is rejected
# before NumPy's permissive string-to-number conversion sees it.
_FLOAT_OK = np.zeros(256, dtype=bool)
_FLOAT_OK[np.frombuffer(b"0123456789+-.eE ", dtype=np.uint8)] = True
_INT_OK = np.zeros(256, dtype=bool)
_INT_OK[np.frombuffer(b"0123456789+- ", dtype=np.uint8)] = True


def existing_file(path: str | Path) -> Path:
    """Return ``path`` as a :class:`Path`, raising :class:`InputError` if it is not a file.

    An empty path, a directory and a file the user may not read are named as such
    (:func:`starsense._io.readable_file`).
    """
    return readable_file(path, "catalogue file")


def read_bytes(path: Path) -> bytes:
    """Read a whole file, transparently decompressing ``*.gz``."""
    try:
        if path.suffix == ".gz":
            with gzip.open(path, "rb") as f:
                return f.read()
        return path.read_bytes()
    except (OSError, EOFError, zlib.error) as exc:
        raise CatalogFormatError(str(path), detail=f"cannot read file: {exc}") from exc


@dataclass(frozen=True)
class Field:
    """One field of a fixed-width record.

    Bytes are in the 1-based inclusive convention of the CDS/VizieR ReadMe files
    ("Byte-by-byte Description").
    """

    name: str
    start: int
    end: int

    @property
    def width(self) -> int:
        return self.end - self.start + 1


def _text(row: np.ndarray) -> str:
    return bytes(row).decode("ascii", errors="replace").strip()


class FixedWidthRecords:
    """A fixed-width text file viewed as a 2-D byte array.

    Parameters
    ----------
    path : Path
        The file (for error messages).
    data : bytes
        Its content.
    fields : sequence of Field
        All fields of the record, in byte order (used to name the field a truncated record
        cuts).
    min_length, max_length : int
        Allowed record lengths in bytes, line terminator excluded. ``CR LF`` terminators are
        accepted; empty lines are skipped.
    """

    def __init__(
        self,
        path: Path,
        data: bytes,
        fields: Sequence[Field],
        *,
        min_length: int,
        max_length: int,
    ) -> None:
        self.path = str(path)
        self.fields = tuple(fields)
        if not data or data.isspace():  # isspace() stops at the first other byte
            raise CatalogFormatError(self.path, detail="file is empty")
        if b"\r" in data:
            data = data.replace(b"\r\n", b"\n")
        if not data.endswith(b"\n"):
            data += b"\n"
        block = self._fast_split(data, min_length, max_length)
        self._data: bytes | None = None  # the raw bytes, when every line is one record
        if block is not None:
            self.block = block
            self.line_no = np.arange(1, block.shape[0] + 1, dtype=np.int64)
            self._data = data
        else:
            self.block, self.line_no = self._slow_split(data, min_length, max_length)

    def __len__(self) -> int:
        return self.block.shape[0]

    @staticmethod
    def _fast_split(data: bytes, min_length: int, max_length: int) -> np.ndarray | None:
        """All lines the same length: a zero-copy reshape. Returns None if not applicable."""
        length = data.index(b"\n")
        if not min_length <= length <= max_length or len(data) % (length + 1):
            return None
        arr = np.frombuffer(data, dtype=np.uint8).reshape(-1, length + 1)
        # every row ends in a newline and there are no others: all lines have this length
        if data.count(b"\n") != arr.shape[0] or not (arr[:, length] == _NEWLINE).all():
            return None
        return arr[:, :length]

    def _slow_split(
        self, data: bytes, min_length: int, max_length: int
    ) -> tuple[np.ndarray, np.ndarray]:
        lines = data.split(b"\n")[:-1]
        lengths = np.fromiter(map(len, lines), dtype=np.int64, count=len(lines))
        keep = lengths > 0
        bad = keep & ((lengths < min_length) | (lengths > max_length))
        if bad.any():
            i = int(np.argmax(bad))
            n = int(lengths[i])
            if n > max_length:
                raise CatalogFormatError(
                    self.path,
                    detail=f"record is {n} bytes long, expected at most {max_length} "
                    "(wrong record length: is this the right catalogue format?)",
                    line=i + 1,
                )
            cut = next((f for f in self.fields if f.end > n), None)
            raise CatalogFormatError(
                self.path,
                detail=f"record is truncated: {n} bytes long, expected at least {min_length}"
                + (f" (field {cut.name} occupies bytes {cut.start}-{cut.end})" if cut else ""),
                line=i + 1,
                field=cut.name if cut else None,
            )
        line_no = np.flatnonzero(keep).astype(np.int64) + 1
        if line_no.size == 0:
            raise CatalogFormatError(self.path, detail="file is empty")
        width = int(lengths.max())
        kept = [lines[i] for i in line_no - 1] if line_no.size != len(lines) else lines
        block = np.array(kept, dtype=f"S{width}").view(np.uint8).reshape(-1, width)
        block[block == 0] = _SPACE  # NumPy pads short byte strings with NULs
        return block, line_no

    # -- errors ---------------------------------------------------------------------------
    def fail(self, row: int, field: str | None, detail: str) -> CatalogFormatError:
        """Build the error for record ``row`` (0-based index into this table)."""
        return CatalogFormatError(
            self.path, detail=detail, line=int(self.line_no[row]), field=field
        )

    def _raw(self, f: Field) -> np.ndarray:
        return self.block[:, f.start - 1 : f.end]

    # -- converters -----------------------------------------------------------------------
    def expect_separators(self, char: bytes, count: int) -> None:
        """Every record must hold exactly ``count`` occurrences of ``char``."""
        if self._data is not None and self._data.count(char) == count * len(self):
            return  # C-speed check on the raw bytes; the per-record count finds culprits
        found = (self.block == ord(char)).sum(axis=1)
        bad = found != count
        if bad.any():
            i = int(np.argmax(bad))
            raise self.fail(
                i,
                None,
                f"found {int(found[i])} {char.decode()!r} field separators, expected {count} "
                "(wrong record layout)",
            )

    def expect_byte(self, byte: int, char: bytes, after: Field) -> None:
        """Byte ``byte`` (1-based) must be ``char`` (the separator after field ``after``)."""
        bad = self.block[:, byte - 1] != ord(char)
        if bad.any():
            i = int(np.argmax(bad))
            got = chr(int(self.block[i, byte - 1]))
            raise self.fail(
                i,
                after.name,
                f"expected {char.decode()!r} at byte {byte} after field {after.name}, "
                f"found {got!r} (misaligned record)",
            )

    def blank(self, f: Field) -> np.ndarray:
        """Boolean mask of records where field ``f`` is all spaces."""
        return (self._raw(f) == _SPACE).all(axis=1)

    def floats(self, f: Field, *, required: bool = False) -> np.ndarray:
        """Field ``f`` as float64; blank fields become NaN unless ``required``."""
        return self._numbers(f, np.float64, _FLOAT_OK, required)

    def ints(self, f: Field, *, required: bool = True, fill: int = 0) -> np.ndarray:
        """Field ``f`` as int64; blank fields become ``fill`` unless ``required``."""
        return self._numbers(f, np.int64, _INT_OK, required, fill=fill)

    def strings(self, f: Field) -> np.ndarray:
        """Field ``f`` as a NumPy unicode array, surrounding blanks removed."""
        raw = np.ascontiguousarray(self._raw(f)).view(f"S{f.width}").reshape(-1)
        return np.char.strip(np.char.decode(raw, "ascii", errors="replace"))

    def chars(self, f: Field) -> np.ndarray:
        """Return a one-byte field as a uint8 array of character codes."""
        return self.block[:, f.start - 1]

    def _numbers(
        self, f: Field, dtype: type, allowed: np.ndarray, required: bool, fill: int = 0
    ) -> np.ndarray:
        block = np.ascontiguousarray(self._raw(f))
        kind = "an integer" if dtype is np.int64 else "a number"
        blank = (block == _SPACE).all(axis=1)
        if required and blank.any():
            i = int(np.argmax(blank))
            raise self.fail(i, f.name, "field is blank but a value is required")
        try:
            values = _arrow_parse(block, blank, dtype)
        except ValueError:
            values = None
        if values is None or (dtype is np.float64 and not np.isfinite(values).all()):
            # The slow, exact pass: the first field with a byte that cannot occur in a
            # number, that Python cannot parse, or that spells NaN or infinity.
            text = block.view(f"S{f.width}").reshape(-1)
            bad = (~allowed[block]).any(axis=1)
            for i in np.flatnonzero(~blank):
                try:
                    ok = not bad[i] and math.isfinite(
                        float(text[i]) if kind == "a number" else int(text[i])
                    )
                except (ValueError, OverflowError):
                    ok = False
                if not ok:
                    raise self.fail(int(i), f.name, f"{_text(block[i])!r} is not {kind}")
            raise CatalogFormatError(  # pragma: no cover - Arrow and Python disagree
                self.path, detail=f"cannot parse field {f.name}", field=f.name
            )
        if blank.any():
            values[blank] = np.nan if dtype is np.float64 else fill
        return values


def _arrow_parse(block: np.ndarray, blank: np.ndarray, dtype: type) -> np.ndarray:
    """Parse the rows of a contiguous ``(N, width)`` byte block as numbers with Arrow.

    Arrow's C++ parser is about twice as fast as NumPy's string cast. Blank rows are masked
    as null and come back as 0; raises ValueError if any other row does not parse.
    """
    import pyarrow as pa
    import pyarrow.compute as pc

    n, width = block.shape
    validity = None
    if blank.any():
        validity = pa.py_buffer(np.packbits(~blank, bitorder="little"))
    binary = pa.FixedSizeBinaryArray.from_buffers(
        pa.binary(width), n, [validity, pa.py_buffer(block)]
    )
    text = pc.utf8_trim_whitespace(binary.cast(pa.binary()).cast(pa.string()))
    target = pa.float64() if dtype is np.float64 else pa.int64()
    try:
        parsed = pc.cast(text, target)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
        raise ValueError(str(exc)) from exc
    return np.array(parsed.fill_null(0).to_numpy(zero_copy_only=False), dtype=dtype)


def check_range(
    path: Path | str,
    values: np.ndarray,
    lo: float,
    hi: float,
    field: str,
    line_no: np.ndarray,
    *,
    hi_inclusive: bool = True,
    unit: str = "deg",
) -> None:
    """Raise :class:`CatalogFormatError` at the first value outside ``[lo, hi]``.

    With ``hi_inclusive=False`` the range is ``[lo, hi)``; NaN counts as outside.
    """
    with np.errstate(invalid="ignore"):
        ok = (values >= lo) & ((values <= hi) if hi_inclusive else (values < hi))
    if not ok.all():
        i = int(np.argmax(~ok))
        if np.isnan(values[i]):
            raise CatalogFormatError(
                str(path), detail="value is missing", line=int(line_no[i]), field=field
            )
        close = "]" if hi_inclusive else ")"
        raise CatalogFormatError(
            str(path),
            detail=f"value {float(values[i])!r} {unit} is outside [{lo}, {hi}{close}",
            line=int(line_no[i]),
            field=field,
        )


# -- delimited text (2MASS, Gaia CSV) ------------------------------------------------------
def open_text(path: Path):
    """Open a (possibly gzipped) text file for the diagnostic pass."""
    if path.suffix == ".gz":
        return gzip.open(path, "rt", encoding="utf-8", errors="replace", newline="")
    return open(path, encoding="utf-8", errors="replace", newline="")


def head_lines(path: Path, n_bytes: int = 1 << 16) -> list[str]:
    """Return the complete lines within the first ``n_bytes`` of a (possibly gzipped) text file."""
    try:
        with open_text(path) as f:
            text = f.read(n_bytes)
    except (OSError, EOFError, zlib.error) as exc:
        raise CatalogFormatError(str(path), detail=f"cannot read file: {exc}") from exc
    lines = text.splitlines()
    if len(text) == n_bytes and lines and not text.endswith(("\n", "\r")):
        lines = lines[:-1]
    return lines


def locate_delimited_error(
    path: Path,
    *,
    delimiter: str,
    names: Sequence[str] | None,
    skip_lines: int,
    numeric: Mapping[str, type],
    required: Sequence[str],
    null_values: Sequence[str],
    quoting: bool,
) -> CatalogFormatError | None:
    """Find the first malformed line of a delimited file.

    This is the slow, exact pass, run only after the fast reader failed.

    Parameters
    ----------
    names : sequence of str or None
        Column names, or None when the first (non-skipped) line is a header.
    skip_lines : int
        Leading lines to ignore (comments).
    numeric : mapping of column name to ``float`` or ``int``
        Columns whose values must parse as numbers.
    required : sequence of str
        Columns that must not be null.
    """
    nulls = set(null_values)
    with open_text(path) as f:
        reader = csv.reader(
            f,
            delimiter=delimiter,
            quoting=csv.QUOTE_MINIMAL if quoting else csv.QUOTE_NONE,
        )
        columns: list[str] | None = list(names) if names is not None else None
        for row in reader:
            line = reader.line_num
            if line <= skip_lines:
                continue
            if columns is None:
                columns = [c.strip() for c in row]
                continue
            if len(row) != len(columns):
                cut = columns[len(row)] if len(row) < len(columns) else None
                return CatalogFormatError(
                    str(path),
                    detail=f"line has {len(row)} fields, expected {len(columns)}"
                    + (" (truncated line?)" if cut else ""),
                    line=line,
                    field=cut,
                )
            for name, kind in numeric.items():
                if name not in columns:
                    continue
                value = row[columns.index(name)].strip()
                if value in nulls:
                    if name in required:
                        return CatalogFormatError(
                            str(path), detail="value is missing", line=line, field=name
                        )
                    continue
                try:
                    kind(value)
                except ValueError:
                    what = "an integer" if kind is int else "a number"
                    return CatalogFormatError(
                        str(path), detail=f"{value!r} is not {what}", line=line, field=name
                    )
    return None


def read_delimited(
    path: Path,
    *,
    delimiter: str,
    names: Sequence[str] | None,
    skip_lines: int,
    types: Mapping[str, object],
    required: Sequence[str],
    null_values: Sequence[str],
    quoting: bool,
) -> dict[str, np.ndarray]:
    """Read selected columns of a delimited text file with :mod:`pyarrow.csv`.

    ``types`` maps column name to a pyarrow type (float64 or int64); integer columns must
    be non-null. Float nulls become NaN. On a parse error the file is re-scanned with
    :func:`locate_delimited_error` to report the exact line and field.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    read_options = pacsv.ReadOptions(
        column_names=list(names) if names is not None else None,
        skip_rows=skip_lines,
        block_size=1 << 24,
    )
    parse_options = pacsv.ParseOptions(
        delimiter=delimiter,
        quote_char='"' if quoting else False,
        ignore_empty_lines=False,
    )
    convert_options = pacsv.ConvertOptions(
        column_types=dict(types),
        include_columns=list(types),
        null_values=list(null_values),
        strings_can_be_null=True,
    )
    try:
        table = pacsv.read_csv(
            path,
            read_options=read_options,
            parse_options=parse_options,
            convert_options=convert_options,
        )
    except (pa.ArrowException, OSError, EOFError, zlib.error) as exc:
        located = locate_delimited_error(
            path,
            delimiter=delimiter,
            names=names,
            skip_lines=skip_lines,
            numeric={k: (int if pa.types.is_integer(t) else float) for k, t in types.items()},
            required=required,
            null_values=null_values,
            quoting=quoting,
        )
        if located is not None:
            raise located from exc
        raise CatalogFormatError(str(path), detail=f"cannot parse file: {exc}") from exc
    out: dict[str, np.ndarray] = {}
    for name in types:
        column = table.column(name)
        if column.null_count and pa.types.is_integer(column.type):
            row = int(np.argmax(column.is_null().to_numpy(zero_copy_only=False)))
            first_data_line = skip_lines + (0 if names is not None else 1) + 1
            raise CatalogFormatError(
                str(path), detail="value is missing", line=first_data_line + row, field=name
            )
        out[name] = column.to_numpy()
    return out
