"""The guide-stars sub-app, tested on its own Typer app (registration is done in cli.py)."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from starsense.cli.guide_stars import guide_stars_app

runner = CliRunner()


def test_simulate_json():
    res = runner.invoke(guide_stars_app, ["simulate", "--json", "--trials", "300"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["sigma_arcsec"] == [0.3, 0.25, 0.2, 0.1, 0.05, 0.02, 0.01]
    assert set(out["probability"]) == {"one", "two_adjacent", "two_symmetric", "three", "four"}
    for v in out["probability"].values():
        assert len(v) == 7
        assert all(0.0 <= p <= 1.0 for p in v)


def test_simulate_text():
    res = runner.invoke(guide_stars_app, ["simulate", "--trials", "200", "--sigmas-arcsec", "0.1"])
    assert res.exit_code == 0, res.output
    assert "Monte Carlo / analytic" in res.output
