"""The design page: its API gives the prediction's numbers; in a real browser (slow), the page."""

from __future__ import annotations

import math
import shutil
import socket
import threading
import time

import pytest

pytest.importorskip("starlette", reason="the web extra (starlette) is not installed")
pytest.importorskip("httpx2", reason="httpx2 (Starlette's test client) is not installed")

from starlette.testclient import TestClient

from starsense.analysis.trade import base_document, predict, prediction_settings
from starsense.sensor import load_sensor
from starsense.sensor.load import sensor_from_dict
from starsense.web.app import create_app

_SKY = {"n_orientations": 150, "n_slew_trials": 4}  # small: the page and API on equal inputs


@pytest.fixture(scope="module")
def client():
    # the server answers only requests to the address it serves (starsense.web.guard)
    with TestClient(create_app("st16", **_SKY), base_url="http://127.0.0.1:8765") as c:
        yield c


def test_page_numbers_are_the_predictions(client):
    doc = base_document("st16")
    doc["optics"]["aperture_m"] = 0.02
    got = client.post("/api/predict", json={"document": doc, "rate_deg_s": 0.5}).json()
    settings = prediction_settings(rate_rad_s=math.radians(0.5), **_SKY)
    want = predict(sensor_from_dict(doc, "design"), settings=settings).to_dict()
    assert got["datasheet"] == want  # the same numbers, bit for bit
    assert got["rows"]["nea_cross"]["value"] == want["nea_arcsec"]["cross"]["median"]


def test_bad_value_names_the_field(client):
    doc = base_document("st16")
    doc["detector"]["pixel_pitch_m"] = -2e-6
    r = client.post("/api/predict", json={"document": doc})
    assert r.status_code == 422
    body = r.json()
    assert body["field"] == "detector.pixel_pitch_m"
    assert "pixel_pitch_m = -2e-06 is out of range" in body["error"]


def test_toml_download_loads_back(client, tmp_path):
    doc = base_document("st16")
    doc["exposure_s"] = 0.25
    r = client.post("/api/toml", json={"document": doc})
    assert r.status_code == 200 and "attachment" in r.headers["content-disposition"]
    path = tmp_path / "d.toml"
    path.write_bytes(r.content)
    assert load_sensor(path) == sensor_from_dict(doc, "design")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_design_page_in_a_real_browser(tmp_path):
    """Change the aperture, see the NEA follow the prediction; a negative pitch's message; pin
    two designs; download the TOML and load it back."""
    if shutil.which("chromium") is None or shutil.which("chromedriver") is None:
        pytest.skip("no browser: Debian's chromium and chromium-driver are not installed")
    selenium = pytest.importorskip("selenium", reason="selenium is not installed")
    import uvicorn
    from selenium.webdriver import Chrome, ChromeOptions
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    assert selenium
    port = _free_port()
    server = uvicorn.Server(
        uvicorn.Config(create_app("st16", port=port, **_SKY), port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.05)
    opts = ChromeOptions()
    opts.binary_location = shutil.which("chromium")
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--window-size=1300,1000",
    ):
        opts.add_argument(arg)
    opts.add_experimental_option("prefs", {"download.default_directory": str(tmp_path)})
    driver = Chrome(service=Service(shutil.which("chromedriver")), options=opts)
    try:
        wait = WebDriverWait(driver, 120)
        driver.get(f"http://127.0.0.1:{port}/")
        wait.until(lambda d: "predicted in" in d.find_element(By.ID, "status").text)
        before = float(driver.find_element(By.ID, "v-nea_cross").get_attribute("data-value"))
        aperture = driver.find_element(By.ID, "f-optics.aperture_m")
        aperture.clear()
        aperture.send_keys("0.024")
        wait.until(
            lambda d: (
                d.find_element(By.ID, "v-nea_cross").get_attribute("data-value")
                not in ("", str(before))
                and "predicted in" in d.find_element(By.ID, "status").text
            )
        )
        after = float(driver.find_element(By.ID, "v-nea_cross").get_attribute("data-value"))
        doc = base_document("st16")
        doc["optics"]["aperture_m"] = 0.024
        want = predict(sensor_from_dict(doc, "x"), settings=prediction_settings(**_SKY))
        assert after == pytest.approx(want.nea_arcsec.cross.median, rel=1e-12)
        assert after < before  # a bigger aperture collects more light
        driver.find_element(By.ID, "pin").click()
        pitch = driver.find_element(By.ID, "f-detector.pixel_pitch_m")
        pitch.clear()
        pitch.send_keys("-3e-6")
        wait.until(
            lambda d: "out of range" in d.find_element(By.ID, "e-detector.pixel_pitch_m").text
        )
        pitch.clear()
        pitch.send_keys("2.2e-6")
        wait.until(lambda d: "predicted in" in d.find_element(By.ID, "status").text)
        driver.find_element(By.ID, "pin").click()
        assert len(driver.find_elements(By.CSS_SELECTOR, "#pinned th.pin")) == 2
        driver.save_screenshot(str(tmp_path / "page.png"))
        driver.find_element(By.ID, "toml").click()
        for _ in range(100):
            files = list(tmp_path.glob("*.toml"))
            if files:
                break
            time.sleep(0.1)
        assert files, "the TOML was not downloaded"
        assert load_sensor(files[0]).optics.aperture_m == 0.024
    finally:
        driver.quit()
        server.should_exit = True
        thread.join(timeout=10)
