"""A trade study: the datasheet's trade rows for every design of a grid, and its Pareto set.

Each design is predicted (:func:`~starsense.analysis.trade.predict.predict`: the datasheet's
models, no frames) in this process, in worker processes, or on a Dask cluster; a design is a
pure function of its TOML document, the catalogue and the seed, so the rows do not depend on
where they were computed. A design whose TOML is out of range gets its own error and the
others go on. ``frames`` > 0 then verifies designs (all, or only the Pareto set) on rendered
frames: the full datasheet, whose predicted numbers are those of the prediction.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from starsense.analysis.datasheet.compare import row_values
from starsense.analysis.datasheet.sheet import DatasheetSettings, build_datasheet
from starsense.analysis.datasheet.skycache import black_bodies
from starsense.analysis.ecss import ecss_statement
from starsense.analysis.ecss.export import statement_rows
from starsense.analysis.inputs import as_catalog
from starsense.analysis.trade.grid import MAX_DESIGNS_IN_PROCESS, MAX_DESIGNS_ON_CLUSTER, Design
from starsense.analysis.trade.keys import named_rows
from starsense.analysis.trade.predict import prediction_settings
from starsense.errors import InputError
from starsense.units import DEG

__all__ = ["PARETO", "TradeRow", "TradeStudy", "pareto_mask", "run_trade"]

#: the Pareto fronts marked: name -> ((row key or design key, "min" | "max"), ...)
PARETO: dict[str, tuple[tuple[str, str], ...]] = {
    "nea_vs_rate": (("nea_cross", "min"), ("fastest_99", "max")),
    "roll_vs_aperture": (("nea_roll", "min"), ("aperture_m", "min")),
}

_CATALOG: dict[str, object] = {}  # the catalogue of this (worker) process, by specification


@dataclass(frozen=True)
class TradeRow:
    """One design of a trade.

    Attributes
    ----------
    index : int
        Its place in the grid.
    name : str
        The design's sensor name.
    values : dict
        The varied (and coupled) keys and their values, TOML units.
    rows : dict or None
        The trade rows (:func:`~starsense.analysis.datasheet.compare.row_values`); None when
        the design could not be evaluated.
    error : str or None
        Why not (a one-line message naming the field).
    aperture_m : float or None
        The design's aperture, m (an axis of a Pareto front).
    pareto : dict
        Front name (:data:`PARETO`) -> on it.
    verified : bool
        Checked on rendered frames (the rows then hold the measured numbers).
    warnings : tuple of str
        The design's datasheet warnings, as ``starsense datasheet`` gives them: a limiting
        magnitude past the catalogue's completeness (its stars, availability and NEA then count
        too few stars), a detection threshold or a bias the noise makes suspicious, ...
    """

    index: int
    name: str
    values: dict
    rows: dict | None
    error: str | None = None
    aperture_m: float | None = None
    pareto: dict | None = None
    verified: bool = False
    warnings: tuple[str, ...] = ()

    def value(self, key: str) -> float | None:
        """Return a trade row's value (or ``aperture_m``), None where missing."""
        if key == "aperture_m":
            return self.aperture_m
        if self.rows is None:
            return None
        return self.rows[key]["value"]

    def to_dict(self) -> dict:
        """Return the JSON form (one line of ``starsense trade --json``).

        The rows are keyed by their names with units (:data:`~starsense.analysis.trade.keys.
        OUTPUT_KEYS`: ``nea_cross_arcsec``, ``fastest_rate_99pct_deg_s``, ...).
        """
        return {
            "index": self.index,
            "design": self.name,
            "values": dict(self.values),
            "rows": named_rows(self.rows),
            "error": self.error,
            "pareto": dict(self.pareto or {}),
            "verified": self.verified,
            "warnings": list(self.warnings),
        }


@dataclass(frozen=True)
class TradeStudy:
    """The rows of a trade, in grid order.

    Attributes
    ----------
    rows : tuple of TradeRow
    keys : tuple of str
        The varied keys.
    settings : DatasheetSettings
        How every design was predicted (the seed is shared).
    """

    rows: tuple[TradeRow, ...]
    keys: tuple[str, ...]
    settings: DatasheetSettings


def _catalog(spec):
    key = "" if spec is None else str(spec)
    if key not in _CATALOG:
        _CATALOG.clear()
        _CATALOG[key] = as_catalog(spec)
    return _CATALOG[key]


def evaluate_design(
    design: Design,
    catalog=None,
    *,
    settings: DatasheetSettings,
    n_frames: int = 0,
    statement: bool = False,
) -> TradeRow:
    """Return the trade row of one design (its error, when its TOML is out of range).

    Parameters
    ----------
    design : Design
        The design.
    catalog : Catalog, str or None
        The catalogue or its specification (loaded once per process).
    settings : DatasheetSettings
        The prediction's settings.
    n_frames : int
        Rendered frames to verify it on (0: the prediction alone).
    statement : bool
        Add the ECSS statement's totals per axis at rest and at the settings' rate (1 sigma;
        :func:`~starsense.analysis.ecss.ecss_statement` on the design's datasheet).

    Returns
    -------
    TradeRow
    """
    try:
        sensor = design.sensor()
    except InputError as exc:
        return TradeRow(
            design.index, design.document.get("name", ""), design.values, None, str(exc)
        )
    cat = catalog if not isinstance(catalog, str | type(None)) else _catalog(catalog)
    st = replace(settings, n_trials=n_frames, n_rate_trials=n_frames)
    try:
        sheet = build_datasheet(sensor, cat, settings=st)
    except InputError as exc:
        return TradeRow(design.index, sensor.name, design.values, None, str(exc))
    payload = sheet.to_dict()
    if statement and sheet.limiting_magnitude is not None:
        rates = (0.0, st.rate_rad_s / DEG)
        stated = ecss_statement(sensor, cat, rates_deg_s=rates, settings=st, sheet=sheet)
        payload["statement"] = {"rows": statement_rows(stated)}
    return TradeRow(
        design.index,
        sensor.name,
        design.values,
        row_values(payload),
        aperture_m=sensor.optics.aperture_m,
        verified=n_frames > 0,
        warnings=tuple(sheet.warnings),
    )


def pareto_mask(points: np.ndarray) -> np.ndarray:
    """Return which points no other point dominates (every objective minimised).

    Parameters
    ----------
    points : ndarray (N, K)
        Objectives to minimise; rows with a NaN are never on the front.

    Returns
    -------
    ndarray (N,) of bool
    """
    p = np.asarray(points, dtype=float)
    ok = np.all(np.isfinite(p), axis=1)
    out = np.zeros(len(p), dtype=bool)
    for i in np.flatnonzero(ok):
        others = p[ok]
        dominated = np.any(np.all(others <= p[i], axis=1) & np.any(others < p[i], axis=1))
        out[i] = not dominated
    return out


def _mark_pareto(rows: list[TradeRow]) -> list[TradeRow]:
    marks = {}
    for name, axes in PARETO.items():
        pts = np.array(
            [
                [_objective(r.value(key), sense) if r.rows else np.nan for key, sense in axes]
                for r in rows
            ],
            dtype=float,
        ).reshape(len(rows), len(axes))
        marks[name] = pareto_mask(pts)
    return [
        replace(r, pareto={n: bool(m[i]) for n, m in marks.items()}) for i, r in enumerate(rows)
    ]


def _objective(value, sense: str) -> float:
    """Return the value as a quantity to minimise (a rate never kept counts as -1 deg/s)."""
    if value is None:
        return 1.0 if sense == "max" else np.nan
    return -float(value) if sense == "max" else float(value)


def _map(func, designs, *, workers: int, client, progress):
    """Evaluate ``func`` over ``designs`` in order: here, in worker processes or on Dask."""
    n = len(designs)
    if client is not None:
        futures = client.map(func, designs, pure=False)
        out = client.gather(futures)
        if progress is not None:
            progress("trade", n, n)
        return list(out)
    if workers <= 1 or n <= 1:
        out = []
        for k, d in enumerate(designs):
            out.append(func(d))
            if progress is not None:
                progress("trade", k + 1, n)
        return out
    ctx = multiprocessing.get_context("fork")  # workers share the parent's catalogue pages
    out: list = [None] * n
    with concurrent.futures.ProcessPoolExecutor(workers, mp_context=ctx) as pool:
        jobs = {
            pool.submit(_evaluate_many, func, [designs[k] for k in chunk]): chunk
            for chunk in _field_chunks(designs, workers)
        }
        done = 0
        for job in concurrent.futures.as_completed(jobs):
            for k, row in zip(jobs[job], job.result(), strict=True):
                out[k] = row
            done += len(jobs[job])
            if progress is not None:
                progress("trade", done, n)
    return out


def _evaluate_many(func, designs) -> list:
    """Evaluate ``func`` over a chunk of designs in one worker."""
    return [func(d) for d in designs]


def _field_key(design) -> tuple | None:
    """Return the field a design looks through (its sky geometry's key); None if invalid."""
    try:
        sensor = design.sensor()
    except InputError:
        return None
    det = sensor.detector
    return (sensor.optics.focal_length_m, det.columns, det.rows, det.pixel_pitch_m)


def _field_chunks(designs, workers: int) -> list[list[int]]:
    """Split the designs into chunks for ``workers`` processes, each field in as few as can be.

    The designs sharing a field share its sky geometry (computed once per process,
    :mod:`starsense.analysis.datasheet.skycache`): they are kept in one chunk, unless there
    are fewer fields than twice the workers, when each field is split evenly so that every
    worker gets work.
    """
    groups: dict = {}
    for k, d in enumerate(designs):
        groups.setdefault(_field_key(d), []).append(k)
    parts = max(1, -(-2 * workers // len(groups)))  # pieces per field
    chunks = []
    for idx in groups.values():
        size = -(-len(idx) // parts)
        chunks += [idx[i : i + size] for i in range(0, len(idx), size)]
    return sorted(chunks, key=len, reverse=True)  # the longest first


class _Evaluate:
    """Picklable ``design -> TradeRow`` (for worker processes and Dask)."""

    def __init__(self, catalog, settings, n_frames: int, statement: bool = False) -> None:
        self.catalog, self.settings, self.n_frames = catalog, settings, n_frames
        self.statement = statement

    def __call__(self, design: Design) -> TradeRow:
        return evaluate_design(
            design,
            self.catalog,
            settings=self.settings,
            n_frames=self.n_frames,
            statement=self.statement,
        )


def run_trade(
    designs: Sequence[Design],
    catalog: str | None = None,
    *,
    settings: DatasheetSettings | None = None,
    n_frames: int = 0,
    verify: str = "all",
    workers: int = 1,
    client=None,
    progress: Callable[[str, int, int], None] | None = None,
    statement: bool = False,
) -> TradeStudy:
    """Predict every design, mark the Pareto sets, and verify on frames if asked.

    Parameters
    ----------
    designs : sequence of Design
        From :func:`~starsense.analysis.trade.grid.designs`.
    catalog : str or None
        Catalogue specification (None: the bundled Hipparcos), loaded once per process.
    settings : DatasheetSettings, optional
        Default :func:`~starsense.analysis.trade.predict.prediction_settings`.
    n_frames : int
        Rendered frames per design at rest and at the rate to verify on (0: none).
    verify : {"all", "pareto"}
        Which designs to verify when ``n_frames`` > 0 (``pareto``: those on any front).
    workers : int
        Processes on this machine (ignored with ``client``).
    client : dask.distributed.Client, optional
        Evaluate the designs on this cluster (the same rows).
    progress : callable(label, done, total), optional
    statement : bool
        Add each design's ECSS statement totals per axis, at rest and at the settings' rate
        (1 sigma; the design's own sky, as ``datasheet --statement``; a few seconds a design).

    Returns
    -------
    TradeStudy
    """
    if verify not in ("all", "pareto"):
        raise InputError(f"--verify must be all or pareto, got {verify!r}")
    designs = list(designs)
    cap = MAX_DESIGNS_IN_PROCESS if client is None else MAX_DESIGNS_ON_CLUSTER
    if len(designs) > cap:
        raise InputError(
            f"{len(designs):,} designs are more than {cap:,}"
            f"{' without a Dask client' if client is None else ''}; narrow the grid"
        )
    st = settings or prediction_settings()
    if client is None:  # loaded, and its stars fitted as black bodies, before the workers fork
        try:
            black_bodies(_catalog(catalog))
        except InputError:  # no colours: each design's row says so
            pass
    rows = _map(
        _Evaluate(catalog, st, 0, statement),
        list(designs),
        workers=workers,
        client=client,
        progress=progress,
    )
    rows = _mark_pareto(rows)
    if n_frames > 0:
        chosen = [
            r.index
            for r in rows
            if r.rows is not None and (verify == "all" or any((r.pareto or {}).values()))
        ]
        by_index = {d.index: d for d in designs}
        checked = _map(
            _Evaluate(catalog, st, n_frames, statement),
            [by_index[i] for i in chosen],
            workers=workers,
            client=client,
            progress=progress,
        )
        for row in checked:
            pos = next(k for k, r in enumerate(rows) if r.index == row.index)
            rows[pos] = replace(row, pareto=rows[pos].pareto)
    keys = tuple(designs[0].values) if designs else ()
    return TradeStudy(tuple(rows), keys, st)
