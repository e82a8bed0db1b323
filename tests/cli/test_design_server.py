"""The design server serves this machine's page only, within bounds, and stops when told.

Against the app (Starlette's test client): a foreign Host, a cross-origin or non-JSON POST and
a body over 1 MB are refused; every malformed request is a 4xx with a one-line JSON error;
at most two verifications run at once (the rest get 429), frames per verification are capped,
and stopping the app ends the verifications' processes. Against a real server on 127.0.0.1
(``starsense design`` in a subprocess): with 50 verification requests sent at once, a
prediction is answered within 5 s, and SIGTERM ends the server, and its verifications, within
2 s.
"""

from __future__ import annotations

import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("starlette", reason="the web extra (starlette) is not installed")
pytest.importorskip("httpx2", reason="httpx2 (Starlette's test client) is not installed")

from starlette.testclient import TestClient

from starsense.analysis.trade import base_document
from starsense.catalog import load_catalog
from starsense.errors import InputError
from starsense.web.app import create_app
from starsense.web.guard import MAX_BODY_BYTES
from starsense.web.jobs import MAX_FRAMES, MAX_RUNNING

_SKY = {"n_orientations": 150, "n_slew_trials": 4}
PORT = 8765
BASE = f"http://127.0.0.1:{PORT}"
JSON = {"content-type": "application/json"}


@pytest.fixture(scope="module")
def app():
    return create_app("st16", port=PORT, **_SKY)


@pytest.fixture(scope="module")
def client(app):
    with TestClient(app, base_url=BASE) as c:
        yield c


@pytest.fixture(scope="module")
def doc() -> dict:
    return base_document("st16")


def _one_line_error(r, status: int) -> str:
    assert r.status_code == status, (r.status_code, r.text)
    assert r.headers["content-type"].startswith("application/json")
    error = r.json()["error"]
    assert isinstance(error, str) and error and "\n" not in error
    return error


# -- Host ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "host", ["evil.example.com", f"evil.example.com:{PORT}", "127.0.0.1:9999", "127.0.0.1", ""]
)
def test_a_foreign_host_is_refused(client, doc, host):
    # DNS rebinding: a foreign name resolved to 127.0.0.1 still says its name in Host
    said = _one_line_error(client.get("/api/base", headers={"host": host}), 421)
    assert f"Host {host!r} is not this server" in said
    r = client.post("/api/toml", json={"document": doc}, headers={"host": host})
    _one_line_error(r, 421)


@pytest.mark.parametrize("host", [f"127.0.0.1:{PORT}", f"localhost:{PORT}", f"[::1]:{PORT}"])
def test_this_machine_is_served(client, doc, host):
    assert client.get("/", headers={"host": host}).status_code == 200
    r = client.post("/api/toml", json={"document": doc}, headers={"host": host})
    assert r.status_code == 200 and r.text.startswith("name = ")


# -- Origin and content type --------------------------------------------------------------------


@pytest.mark.parametrize(
    "headers",
    [
        {"origin": "http://evil.example.com"},
        {"origin": "null"},  # a sandboxed frame or a file:// page
        {"origin": f"http://127.0.0.1:{PORT + 1}"},  # another local page
        {"sec-fetch-site": "cross-site"},
        {"sec-fetch-site": "same-site"},
    ],
)
def test_a_cross_origin_post_is_refused(client, doc, headers):
    r = client.post("/api/toml", json={"document": doc}, headers=headers)
    assert "cross-origin" in _one_line_error(r, 403)


def test_the_page_own_post_is_served(client, doc):
    headers = {"origin": BASE, "sec-fetch-site": "same-origin"}
    assert client.post("/api/toml", json={"document": doc}, headers=headers).status_code == 200


@pytest.mark.parametrize(
    "kind", ["text/plain", "application/x-www-form-urlencoded", "multipart/form-data", None]
)
def test_a_post_that_is_not_json_is_refused(client, doc, kind):
    # the content types a cross-site form or fetch sends without a preflight
    headers = {} if kind is None else {"content-type": kind}
    r = client.post("/api/verify", content=json.dumps({"document": doc}), headers=headers)
    assert "application/json" in _one_line_error(r, 415)


# -- body size ----------------------------------------------------------------------------------


def test_a_10_mb_body_is_refused(client):
    r = client.post("/api/predict", content=b" " * 10_000_000, headers=JSON)
    assert "10,000,000 bytes" in _one_line_error(r, 413)


def test_a_chunked_body_over_1_mb_is_refused(client):
    def chunks():  # no Content-Length: counted as it comes
        for _ in range(20):
            yield b" " * 100_000

    r = client.post("/api/predict", content=chunks(), headers=JSON)
    assert f"{MAX_BODY_BYTES:,}" in _one_line_error(r, 413)


def test_a_body_at_the_limit_is_read(client):
    body = b'{"document": 1}'.ljust(MAX_BODY_BYTES)  # JSON allows the trailing blanks
    r = client.post("/api/toml", content=body, headers=JSON)
    assert "no design document" in _one_line_error(r, 422)


# -- malformed requests -------------------------------------------------------------------------


def _with(doc: dict, **changes) -> bytes:
    return json.dumps({"document": doc, **changes}).encode()


BAD_BODIES = [
    (b"{not json", 400, "not JSON"),
    (b"", 400, "not JSON"),
    (b"[1, 2]", 400, "JSON object, got an array"),
    (b'"text"', 400, "JSON object, got a string"),
    (b"null", 400, "JSON object, got null"),
    (b'{"document": {}, "x": \xff}', 400, "not UTF-8: byte 0xff"),
    (b'{"rate_deg_s": NaN}', 400, "NaN is not a JSON number"),
    (b"[" * 100_000 + b"]" * 100_000, 400, "nested too deeply"),
    (b"{}", 422, "no design document"),
    (b'{"document": [1]}', 422, "no design document"),
]


@pytest.mark.parametrize(("body", "status", "said"), BAD_BODIES)
@pytest.mark.parametrize("route", ["/api/predict", "/api/toml", "/api/datasheet", "/api/verify"])
def test_a_malformed_body_is_a_4xx_with_one_line(client, route, body, status, said):
    assert said in _one_line_error(client.post(route, content=body, headers=JSON), status)


BAD_FIELDS = [
    ({"seed": "abc"}, "seed = 'abc': must be an integer"),
    ({"seed": -1}, "seed = -1 is out of range"),
    ({"seed": 1.5}, "seed = 1.5: must be an integer"),
    ({"seed": True}, "seed = True: must be an integer"),
    ({"seed": 10**30}, "is out of range"),
    ({"rate_deg_s": "fast"}, "rate_deg_s = 'fast': must be a number"),
    ({"rate_deg_s": None}, "rate_deg_s = None: must be a number"),
    ({"rate_deg_s": 31}, "rate_deg_s = 31 is out of range; must be in [0, 30]"),
    ({"rate_deg_s": 10**400}, "rate_deg_s = 1000"),
]


@pytest.mark.parametrize(("change", "said"), BAD_FIELDS)
@pytest.mark.parametrize("route", ["/api/predict", "/api/datasheet", "/api/verify"])
def test_a_field_of_the_wrong_type_is_a_422(client, doc, route, change, said):
    r = client.post(route, content=_with(doc, **change), headers=JSON)
    assert said in _one_line_error(r, 422)


@pytest.mark.parametrize(
    ("frames", "said"),
    [
        ("many", "frames = 'many': must be an integer"),
        (0, f"frames = 0 is out of range; must be in [1, {MAX_FRAMES}]"),
        (MAX_FRAMES + 1, f"frames = {MAX_FRAMES + 1} is out of range"),
        (1000, f"must be in [1, {MAX_FRAMES}]"),
    ],
)
def test_frames_per_verification_are_capped(client, doc, frames, said):
    r = client.post("/api/verify", content=_with(doc, frames=frames), headers=JSON)
    assert said in _one_line_error(r, 422)


@pytest.mark.parametrize(
    ("section", "key", "value"),
    [
        ("detector", "passband_nm", 400.0),  # a number where a pair goes
        ("detector", "passband_nm", None),
        ("optics", "aperture_m", "wide"),
        ("optics", "aperture_m", [1, 2]),
    ],
)
def test_a_design_value_of_the_wrong_type_is_a_422(client, doc, section, key, value):
    bad = json.loads(json.dumps(doc))
    bad[section][key] = value
    for route in ("/api/predict", "/api/toml", "/api/verify"):
        r = client.post(route, content=_with(bad), headers=JSON)
        assert key in _one_line_error(r, 422) or "cannot be read" in r.json()["error"]


def test_unknown_routes_and_methods_are_json(client):
    assert _one_line_error(client.get("/api/nothing"), 404) == "Not Found"
    assert _one_line_error(client.get("/api/predict"), 405) == "Method Not Allowed"
    assert "no such verification" in _one_line_error(client.get("/api/verify/999"), 404)


# -- verifications ------------------------------------------------------------------------------


def test_at_most_two_verifications_run_and_stopping_ends_them(doc):
    app = create_app("st16", port=PORT, **_SKY)
    page = app.state.page
    with TestClient(app, base_url=BASE) as c:
        body = _with(doc, frames=MAX_FRAMES)
        ids = [c.post("/api/verify", content=body, headers=JSON).json()["id"] for _ in range(2)]
        assert MAX_RUNNING == 2 and page.verifications.running() == 2
        r = c.post("/api/verify", content=body, headers=JSON)
        assert "at most 2 at once" in _one_line_error(r, 429)
        assert r.headers["retry-after"] == "10"
        processes = [page.verifications._jobs[i].process for i in ids]
        assert all(p.poll() is None for p in processes)  # still working
        # held while a prediction runs (SIGSTOP), going on after it (SIGCONT)
        with page.verifications.paused():
            assert _states(processes, stopped=True)
        assert _states(processes, stopped=False)
        t0 = time.perf_counter()
    # the app stopped (its lifespan ended): the verifications' processes are gone at once
    assert all(p.poll() is not None for p in processes)
    assert time.perf_counter() - t0 < 2.0
    for i in ids:
        assert page.verifications.status(i)["error"] == "cancelled: the server is stopping"
    assert page.verifications.running() == 0


def _states(processes, *, stopped: bool, wait_s: float = 2.0) -> bool:
    """Whether every process is (or is not) stopped within ``wait_s`` (signals take a moment)."""
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        states = []
        for p in processes:
            with open(f"/proc/{p.pid}/stat") as fh:
                states.append(fh.read().rsplit(") ", 1)[1][0])
        if all((s == "T") == stopped for s in states):
            return True
        time.sleep(0.02)
    return False


# -- a real server ------------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _request(port: int, method: str, path: str, body: dict | None = None, timeout=60.0):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        data = None if body is None else json.dumps(body)
        conn.request(method, path, body=data, headers=JSON if body is not None else {})
        r = conn.getresponse()
        return r.status, json.loads(r.read() or b"null")
    finally:
        conn.close()


def _children(pid: int) -> list[int]:
    """The process's children, from the parent pid in each /proc/N/stat (Linux)."""
    out = []
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat") as fh:
                fields = fh.read().rsplit(") ", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if int(fields[1]) == pid:
            out.append(int(name))
    return out


def _gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(") ", 1)[1].startswith("Z")  # a zombie: ended, not yet reaped
    except OSError:
        return True


@pytest.fixture
def server():
    port = _free_port()
    cmd = [sys.executable, "-c", "from starsense.cli import console_main; console_main()"]
    args = ["design", "--no-open", "--port", str(port)]
    # a light sky: the test is of the server staying responsive, not of the prediction's cost
    # (about 1 s alone here; the default sky takes 5 s alone on a loaded 2-core machine)
    args += ["--n-orientations", "50", "--slew-trials", "2"]
    proc = subprocess.Popen([*cmd, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                if _request(port, "GET", "/api/base", timeout=5)[0] == 200:
                    break
            except OSError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                raise AssertionError(f"the server did not start: {proc.communicate()}")
            time.sleep(0.2)
        yield proc, port
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


@pytest.mark.slow
def test_a_real_server_under_50_verifications_then_sigterm(server, doc):
    proc, port = server
    status, _ = _request(port, "POST", "/api/predict", {"document": doc})  # warm: first loads
    assert status == 200
    t0 = time.perf_counter()
    assert _request(port, "POST", "/api/predict", {"document": doc, "rate_deg_s": 0.5})[0] == 200
    alone_s = time.perf_counter() - t0
    # 50 verification requests at once, each on its own connection
    start = threading.Barrier(50)
    answers: list[tuple[int, dict]] = []

    def verify() -> None:
        start.wait()
        answers.append(_request(port, "POST", "/api/verify", {"document": doc, "frames": 50}))

    threads = [threading.Thread(target=verify) for _ in range(50)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    statuses = sorted(s for s, _ in answers)
    assert statuses == [200] * 2 + [429] * 48, statuses
    assert all("at most 2" in a["error"] for s, a in answers if s == 429)
    children = _children(proc.pid)
    assert len(children) == 2  # the two verifications' processes
    time.sleep(3.0)  # the verifications are rendering now
    t0 = time.perf_counter()
    status, body = _request(port, "POST", "/api/predict", {"document": doc, "rate_deg_s": 0.5})
    predict_s = time.perf_counter() - t0
    assert status == 200 and body["rows"]["nea_cross"]["value"] > 0
    assert predict_s < 5.0, f"a prediction took {predict_s:.1f} s beside two verifications"
    # SIGTERM with a prediction in flight and both verifications running
    threading.Thread(
        target=lambda: _try(_request, port, "POST", "/api/predict", {"document": doc}), daemon=True
    ).start()
    time.sleep(0.3)
    t0 = time.perf_counter()
    proc.send_signal(signal.SIGTERM)
    code = proc.wait(10)
    stop_s = time.perf_counter() - t0
    assert code == 143, proc.communicate()
    assert stop_s < 2.0, f"SIGTERM took {stop_s:.2f} s"
    print(
        f"prediction alone {alone_s:.2f} s, beside 2 verifications {predict_s:.2f} s; "
        f"SIGTERM to exit {stop_s:.2f} s"
    )
    deadline = time.monotonic() + 1.0
    while not all(_gone(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_gone(c) for c in children), "a verification outlived its server"
    err = proc.communicate()[1].decode()
    assert "Traceback" not in err, err


def _try(fn, *args):
    try:
        return fn(*args)
    except OSError:  # the server went away mid-request: expected here
        return None


def test_the_page_takes_a_catalogue_specification_not_a_loaded_one():
    # its verifications load the catalogue in their own processes, from the specification
    with pytest.raises(InputError, match=r"catalogue specification .* not a loaded catalogue"):
        create_app("st16", load_catalog("hipparcos"), **_SKY)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_while_the_server_starts_stops_it_in_one_line(signum):
    # the signal comes while the server's event loop is being made (before the server listens
    # for signals itself): it used to unwind the loop half made, an "Exception ignored"
    # traceback and a coroutine never awaited; held, it stops the server as soon as it starts.
    # (In a process of its own: the server imports trio, whose hypothesis hook warns here.)
    port = _free_port()
    script = (
        "import os, uvicorn\n"
        "real = uvicorn.Config.get_loop_factory\n"
        "def factory(self):\n"
        f"    os.kill(os.getpid(), {int(signum)})\n"
        "    return real(self)\n"
        "uvicorn.Config.get_loop_factory = factory\n"
        "from starsense.cli import main\n"
        f"raise SystemExit(main(['design', '--no-open', '--port', '{port}', "
        "'--n-orientations', '50']))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 128 + signum, proc.stderr
    assert len(err) == 1 and err[0].startswith("error: "), proc.stderr
