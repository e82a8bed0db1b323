"""The design page's server: edit a sensor, see its datasheet's predictions, verify on frames.

Routes (JSON in and out; a design is a sensor TOML document as a JSON object):

* ``GET /``: the page;
* ``GET /api/base``: the base design and the editable fields;
* ``POST /api/predict`` ``{"document", "rate_deg_s", "seed"}``: the datasheet's trade rows,
  headline numbers and the slew-tolerance figure (PNG, base64) from
  :func:`starsense.analysis.trade.predict`, or ``{"error", "field"}`` with the loader's one-line
  message and the field it names;
* ``POST /api/toml``: the design as a TOML file; ``POST /api/datasheet``: the datasheet JSON
  (the prediction);
* ``POST /api/verify`` (``"frames"`` per rate, at most :data:`~starsense.web.jobs.MAX_FRAMES`):
  start a check on rendered frames; ``GET /api/verify/{id}``: its progress and, when done,
  measured / predicted.

Only this machine's page may use it (:mod:`starsense.web.guard`: Host, Origin, JSON bodies of
at most 1 MB). A malformed request is a 4xx with a one-line JSON ``{"error"}``: 400 for a body
that is not a JSON object (:mod:`starsense.web.payload`), 422 for a design or a field that is
wrong, 429 when :data:`~starsense.web.jobs.MAX_RUNNING` verifications run already (each in its
own process, :mod:`starsense.web.jobs`) or :data:`MAX_PENDING` predictions wait. Predictions
run one at a time in daemon threads, so a server told to stop (SIGTERM) never waits for one,
and the verifications are held while one runs; stopping ends the verifications' processes.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import io
import threading
from collections.abc import AsyncIterator, Callable
from dataclasses import replace
from typing import Any

import tomli_w
from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import HTMLResponse, JSONResponse, Response
from starlette.routing import Route

from starsense.analysis.datasheet.compare import row_values
from starsense.analysis.inputs import as_catalog
from starsense.analysis.trade import base_document, predict, prediction_settings
from starsense.errors import InputError, StarsenseError
from starsense.plotting.slew import tolerance_figure
from starsense.sensor.load import sensor_from_dict
from starsense.units import DEG
from starsense.web.guard import Guard
from starsense.web.jobs import MAX_FRAMES, MAX_RUNNING, Busy, Verifications
from starsense.web.page import FIELDS, page_html
from starsense.web.payload import int_field, number_field, read_payload

__all__ = ["MAX_PENDING", "create_app"]

#: predictions waiting or running at once; more are refused (429)
MAX_PENDING = 4
#: the largest seed accepted (NumPy's seed sequences take any integer >= 0; 64 bits are plenty)
MAX_SEED = 2**63 - 1


def _field_of(message: str) -> str | None:
    """Return the field ("detector.pixel_pitch_m") a loader message names, if any."""
    for section, names in FIELDS.items():
        for name, *_ in names:
            key = name if section == "" else f"{section}.{name}"
            if key in message or (section and f"{name} " in message and section in message):
                return key
    return None


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


class _Computations:
    """The page's predictions: one at a time, each in a daemon thread, at most ``limit`` held.

    A daemon thread, not the event loop's thread pool: a server stopping (SIGTERM) exits
    without waiting for a prediction in progress, whose answer nobody will read. ``quiet``
    is held while one runs (the verifications wait).
    """

    def __init__(
        self, quiet: Callable[[], contextlib.AbstractContextManager], limit: int = MAX_PENDING
    ) -> None:
        self.quiet = quiet
        self.limit = limit
        self.pending = 0
        self._count = threading.Lock()
        self._one = threading.Lock()  # one computation at a time: the CPU is the user's

    async def run(self, fn: Callable[..., Any], *args: Any) -> Any:
        with self._count:
            if self.pending >= self.limit:
                raise HTTPException(
                    429, f"{self.pending} predictions are waiting already; try again shortly"
                )
            self.pending += 1
        loop = asyncio.get_running_loop()
        future = loop.create_future()

        def work() -> None:
            try:
                with self._one, self.quiet():
                    outcome = (True, fn(*args))
            except Exception as exc:
                outcome = (False, exc)
            finally:
                with self._count:
                    self.pending -= 1
            with contextlib.suppress(RuntimeError):  # the loop is gone: the server stopped
                loop.call_soon_threadsafe(_settle, future, outcome)

        threading.Thread(target=work, daemon=True, name="starsense-predict").start()
        try:
            return await future
        except asyncio.CancelledError:  # the server is stopping and did not wait: say so
            raise HTTPException(503, "the server is stopping") from None


def _settle(future: asyncio.Future, outcome: tuple[bool, Any]) -> None:
    if future.cancelled():  # the request went away
        return
    ok, value = outcome
    if ok:
        future.set_result(value)
    else:
        future.set_exception(value)


class _Page:
    """The page's state (base design, catalogue, verifications) and its route handlers."""

    def __init__(self, base: str, catalog, sky: dict, max_running: int) -> None:
        if catalog is not None and not isinstance(catalog, str):
            raise InputError(
                "the design page takes a catalogue specification (as --catalog), not a loaded "
                f"catalogue ({type(catalog).__name__}): its verifications load it themselves"
            )
        self.doc = base_document(base)
        self.cat = as_catalog(catalog)
        self.sky = sky
        self.verifications = Verifications(catalog, max_running)
        self.computations = _Computations(self.verifications.paused)

    @staticmethod
    def document_of(payload: dict) -> dict:
        document = payload.get("document")
        if not isinstance(document, dict):
            raise InputError("the request has no design document (a JSON object)")
        return document

    def sensor_of(self, payload: dict):
        try:
            return sensor_from_dict(self.document_of(payload), source="design")
        except StarsenseError:
            raise
        except Exception as exc:  # a value of a type the loader did not expect
            raise InputError(f"the design cannot be read: {' '.join(str(exc).split())}") from None

    def settings(self, payload: dict):
        rate = number_field(payload, "rate_deg_s", default=1.0, lo=0.0, hi=30.0)
        seed = int_field(payload, "seed", default=0, lo=0, hi=MAX_SEED)
        return prediction_settings(rate_rad_s=rate * DEG, rng=seed, **self.sky)

    async def prediction(self, request: Request, respond: Callable[[Any], Response]) -> Response:
        """Predict the request's design; ``respond`` (the sheet -> the response) runs in the
        computation's thread too: the figure and the JSON are work, not the event loop's."""  # noqa: D205, D209
        payload = await read_payload(request)
        try:
            sensor, settings = self.sensor_of(payload), self.settings(payload)
            return await self.computations.run(
                lambda: respond(predict(sensor, self.cat, settings=settings))
            )
        except StarsenseError as exc:
            return _bad(exc)

    async def index(self, request: Request) -> HTMLResponse:
        return HTMLResponse(page_html())

    async def base(self, request: Request) -> JSONResponse:
        return JSONResponse({"document": self.doc, "fields": FIELDS})

    async def predict_route(self, request: Request) -> Response:
        return await self.prediction(request, _page_response)

    async def toml(self, request: Request) -> Response:
        payload = await read_payload(request)
        try:
            sensor = self.sensor_of(payload)
            text = tomli_w.dumps(payload["document"])
        except StarsenseError as exc:
            return _bad(exc)
        except (TypeError, ValueError) as exc:  # a value TOML cannot hold
            return _bad(InputError(f"the design cannot be written as TOML: {exc}"))
        head = {"Content-Disposition": f'attachment; filename="{_safe(sensor.name)}.toml"'}
        return Response(text, media_type="application/toml", headers=head)

    async def datasheet(self, request: Request) -> Response:
        return await self.prediction(request, _download_response)

    async def verify(self, request: Request) -> JSONResponse:
        payload = await read_payload(request)
        try:
            self.sensor_of(payload)  # refused here, not in the child
            settings = self.settings(payload)
            frames = int_field(payload, "frames", default=20, lo=1, hi=MAX_FRAMES)
        except StarsenseError as exc:
            return _bad(exc)
        st = replace(settings, n_trials=frames, n_rate_trials=frames)
        try:
            job_id = self.verifications.start(payload["document"], st)
        except Busy as exc:
            head = {"Retry-After": "10"}
            return JSONResponse({"error": str(exc)}, status_code=exc.status, headers=head)
        return JSONResponse({"id": job_id})

    async def verify_status(self, request: Request) -> JSONResponse:
        status = self.verifications.status(request.path_params["job"])
        if status is None:
            return JSONResponse({"error": "no such verification"}, status_code=404)
        result = status.pop("result")
        if result is not None:
            status["rows"] = _headline(result)
            status["finished"] = True
        return JSONResponse(status)


def _page_response(sheet) -> JSONResponse:
    """Return the page's answer: headline rows, warnings, the figure, the datasheet."""
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


def _download_response(sheet) -> JSONResponse:
    """Return the datasheet JSON as a download."""
    name = f"{_safe(sheet.sensor)}_datasheet.json"
    return JSONResponse(
        sheet.to_dict(), headers={"Content-Disposition": f'attachment; filename="{name}"'}
    )


def _bad(exc: StarsenseError) -> JSONResponse:
    msg = " ".join(str(exc).split())
    return JSONResponse({"error": msg, "field": _field_of(msg)}, status_code=422)


async def _http_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, HTTPException)
    detail = " ".join(str(exc.detail).split())
    return JSONResponse({"error": detail}, status_code=exc.status_code, headers=exc.headers)


async def _server_error(request: Request, exc: Exception) -> JSONResponse:
    message = " ".join(str(exc).split())[:300]
    return JSONResponse({"error": f"internal error: {type(exc).__name__}: {message}"}, 500)


def create_app(
    base: str = "st16",
    catalog: str | None = None,
    *,
    host: str = "127.0.0.1",
    port: int = 8765,
    n_orientations: int = 2000,
    n_slew_trials: int = 20,
    max_running: int = MAX_RUNNING,
) -> Starlette:
    """Return the page's Starlette app for a base design.

    Parameters
    ----------
    base : str
        Preset name or sensor TOML file the page starts from.
    catalog : str, optional
        Catalogue specification (None: the bundled Hipparcos), loaded once (and once in each
        verification's process).
    host, port : str, int
        Where the server listens: requests naming another host are refused
        (:mod:`starsense.web.guard`).
    n_orientations, n_slew_trials : int
        The prediction's sky boresights and slew renders (the datasheet's defaults, so the
        page shows the numbers of ``starsense datasheet`` and ``starsense trade``).
    max_running : int
        Verifications at once.

    Returns
    -------
    starlette.applications.Starlette
    """
    sky = {"n_orientations": n_orientations, "n_slew_trials": n_slew_trials}
    page = _Page(base, catalog, sky, max_running)

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        try:
            yield
        finally:  # the server stops: end the verifications' processes
            page.verifications.close()

    app = Starlette(
        routes=[
            Route("/", page.index),
            Route("/api/base", page.base),
            Route("/api/predict", page.predict_route, methods=["POST"]),
            Route("/api/toml", page.toml, methods=["POST"]),
            Route("/api/datasheet", page.datasheet, methods=["POST"]),
            Route("/api/verify", page.verify, methods=["POST"]),
            Route("/api/verify/{job}", page.verify_status),
        ],
        middleware=[Middleware(Guard, host=host, port=port)],
        exception_handlers={HTTPException: _http_error, Exception: _server_error},
        lifespan=lifespan,
    )
    app.state.page = page
    return app


def _safe(name: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name)).strip(".")
    return keep or "design"
