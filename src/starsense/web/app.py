"""The design page's server: edit a sensor, see its datasheet's predictions, verify on frames.

Routes (JSON in and out; a design is a sensor TOML document as a JSON object):

* ``GET /``: the page;
* ``GET /api/base``: the base design and the editable fields;
* ``POST /api/predict`` ``{"document", "rate_deg_s"}``: the datasheet's trade rows, headline
  numbers and the slew-tolerance figure (PNG, base64) from
  :func:`starsense.analysis.trade.predict`, or ``{"error", "field"}`` with the loader's one-line
  message and the field it names;
* ``POST /api/toml``: the design as a TOML file; ``POST /api/datasheet``: the datasheet JSON
  (the prediction);
* ``POST /api/verify``: start a check on rendered frames; ``GET /api/verify/{id}``: its
  progress and, when done, measured / predicted.
"""

from __future__ import annotations

import base64
import io
import itertools
import threading
from dataclasses import dataclass, field, replace

import tomli_w
from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import HTMLResponse, JSONResponse, Response
from starlette.routing import Route

from starsense.analysis.datasheet.compare import row_values
from starsense.analysis.datasheet.sheet import build_datasheet
from starsense.analysis.inputs import as_catalog
from starsense.analysis.trade import base_document, predict, prediction_settings
from starsense.errors import InputError
from starsense.plotting.slew import tolerance_figure
from starsense.sensor.load import sensor_from_dict
from starsense.units import DEG
from starsense.web.page import FIELDS, page_html

__all__ = ["create_app"]


@dataclass
class _Job:
    total: int = 6
    done: int = 0
    label: str = "starting"
    result: dict | None = None
    error: str | None = None
    lock: threading.Lock = field(default_factory=threading.Lock)


def _field_of(message: str) -> str | None:
    """Return the field ("detector.pixel_pitch_m") a loader message names, if any."""
    for section, names in FIELDS.items():
        for name, *_ in names:
            key = name if section == "" else f"{section}.{name}"
            if key in message or (section and f"{name} " in message and section in message):
                return key
    return None


def _settings(payload: dict, sky: dict):
    try:
        rate = float(payload.get("rate_deg_s", 1.0))
    except (TypeError, ValueError):
        rate = float("nan")
    if not 0.0 <= rate <= 30.0:
        raise InputError(f"rate_deg_s = {payload.get('rate_deg_s')!r}: must be in [0, 30] deg/s")
    return prediction_settings(rate_rad_s=rate * DEG, rng=int(payload.get("seed", 0)), **sky)


def _headline(d: dict) -> dict:
    rows = row_values(d)
    return {k: v for k, v in rows.items() if v["value"] is not None}


def _figure_png(sheet) -> str | None:
    if sheet.slew is None:
        return None
    fig = tolerance_figure([sheet.slew])
    buf = io.BytesIO()
    fig.set_size_inches(6.0, 3.6)
    fig.savefig(buf, format="png", dpi=80)
    return base64.b64encode(buf.getvalue()).decode()


class _Page:
    """The page's state (base design, catalogue, verification jobs) and its route handlers."""

    def __init__(self, base: str, catalog, sky: dict) -> None:
        self.doc = base_document(base)
        self.cat = as_catalog(catalog)
        self.sky = sky
        self.jobs: dict[str, _Job] = {}
        self.ids = itertools.count(1)
        self.compute = threading.Lock()  # one computation at a time: the CPU is the user's

    @staticmethod
    def sensor_of(payload: dict):
        document = payload.get("document")
        if not isinstance(document, dict):
            raise InputError("the request has no design document")
        return sensor_from_dict(document, source="design")

    def predict(self, payload: dict):
        sensor = self.sensor_of(payload)
        settings = _settings(payload, self.sky)
        with self.compute:
            return predict(sensor, self.cat, settings=settings)

    async def index(self, request: Request) -> HTMLResponse:
        return HTMLResponse(page_html())

    async def base(self, request: Request) -> JSONResponse:
        return JSONResponse({"document": self.doc, "fields": FIELDS})

    async def predict_route(self, request: Request) -> JSONResponse:
        try:
            sheet = await run_in_threadpool(self.predict, await request.json())
        except InputError as exc:
            return _bad(exc)
        d = sheet.to_dict()
        return JSONResponse(
            {
                "sensor": d["sensor"],
                "rows": _headline(d),
                "warnings": list(d.get("warnings", [])),
                "figure_png": _figure_png(sheet),
                "datasheet": d,
            }
        )

    async def toml(self, request: Request) -> Response:
        payload = await request.json()
        try:
            sensor = self.sensor_of(payload)
        except InputError as exc:
            return _bad(exc)
        text = tomli_w.dumps(payload["document"])
        head = {"Content-Disposition": f'attachment; filename="{_safe(sensor.name)}.toml"'}
        return Response(text, media_type="application/toml", headers=head)

    async def datasheet(self, request: Request) -> Response:
        try:
            sheet = await run_in_threadpool(self.predict, await request.json())
        except InputError as exc:
            return _bad(exc)
        head = {
            "Content-Disposition": f'attachment; filename="{_safe(sheet.sensor)}_datasheet.json"'
        }
        return JSONResponse(sheet.to_dict(), headers=head)

    async def verify(self, request: Request) -> JSONResponse:
        payload = await request.json()
        try:
            sensor = self.sensor_of(payload)
            settings = _settings(payload, self.sky)
            frames = int(payload.get("frames", 20))
            if not 1 <= frames <= 1000:
                raise InputError(f"frames = {frames} is out of range; must be in [1, 1000]")
        except (InputError, ValueError, TypeError) as exc:
            return _bad(InputError(str(exc)))
        job_id, job = str(next(self.ids)), _Job()
        self.jobs[job_id] = job
        st = replace(settings, n_trials=frames, n_rate_trials=frames)
        threading.Thread(target=self._work, args=(job, sensor, st), daemon=True).start()
        return JSONResponse({"id": job_id})

    def _work(self, job: _Job, sensor, settings) -> None:
        def progress(label: str, done: int, total: int) -> None:
            with job.lock:
                job.label, job.done, job.total = label, done, total

        try:
            with self.compute:
                sheet = build_datasheet(sensor, self.cat, settings=settings, progress=progress)
            job.result = sheet.to_dict()
        except Exception as exc:  # shown to the user beside the button
            job.error = str(exc)

    async def verify_status(self, request: Request) -> JSONResponse:
        job = self.jobs.get(request.path_params["job"])
        if job is None:
            return JSONResponse({"error": "no such verification"}, status_code=404)
        out = {"done": job.done, "total": job.total, "label": job.label, "error": job.error}
        if job.result is not None:
            out["rows"] = _headline(job.result)
            out["finished"] = True
        return JSONResponse(out)


def _bad(exc: InputError) -> JSONResponse:
    msg = str(exc)
    return JSONResponse({"error": msg, "field": _field_of(msg)}, status_code=422)


def create_app(
    base: str = "st16",
    catalog: str | None = None,
    *,
    n_orientations: int = 2000,
    n_slew_trials: int = 20,
) -> Starlette:
    """Return the page's Starlette app for a base design.

    Parameters
    ----------
    base : str
        Preset name or sensor TOML file the page starts from.
    catalog : str, optional
        Catalogue specification (None: the bundled Hipparcos), loaded once.
    n_orientations, n_slew_trials : int
        The prediction's sky boresights and slew renders (the datasheet's defaults, so the
        page shows the numbers of ``starsense datasheet`` and ``starsense trade``).

    Returns
    -------
    starlette.applications.Starlette
    """
    page = _Page(base, catalog, {"n_orientations": n_orientations, "n_slew_trials": n_slew_trials})
    return Starlette(
        routes=[
            Route("/", page.index),
            Route("/api/base", page.base),
            Route("/api/predict", page.predict_route, methods=["POST"]),
            Route("/api/toml", page.toml, methods=["POST"]),
            Route("/api/datasheet", page.datasheet, methods=["POST"]),
            Route("/api/verify", page.verify, methods=["POST"]),
            Route("/api/verify/{job}", page.verify_status),
        ]
    )


def _safe(name: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name)).strip(".")
    return keep or "design"
