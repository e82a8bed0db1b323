"""The fit's groups laid out in parts of like sizes: a cost, never a different answer."""

from __future__ import annotations

import numpy as np
import pytest
from model_scene import model_image
from scipy.spatial.transform import Rotation

import starsense.model.problem as problem
from starsense.model.fit import fit_windows
from starsense.model.windows import make_windows
from starsense.sensor import load_sensor


def _crowded(seed: int, n: int = 34):
    """The ESA camera with ``n - 4`` stars and 4 close pairs (blends: groups of two)."""
    sensor = load_sensor("esa_blackfly")
    det = sensor.detector
    rng = np.random.default_rng(seed)
    x = rng.uniform(40, det.columns - 40, n)
    y = rng.uniform(40, det.rows - 40, n)
    x[-4:], y[-4:] = x[:4] + rng.uniform(2.5, 4.0, 4), y[:4] + rng.uniform(-1.0, 1.0, 4)
    return sensor, sensor.unproject(x, y)


def _values(parts, windows, per_pixel):
    """The values the parts' arrays hold: groups x grid x (slots + per_pixel)."""
    slots = np.bincount(windows.group[windows.group >= 0], minlength=windows.n_groups)
    return sum(
        len(g) * windows.extent[g, 0].max() * windows.extent[g, 1].max()
        * (slots[g].max() + per_pixel)
        for g in parts
    )  # fmt: skip


def test_the_parts_hold_every_group_once_and_less_padding():
    """Every group in exactly one part; the parts' arrays hold fewer values than one grid.

    200 stars (an ST-16 frame's count): the blends' wider grids are worth parts of their own.
    """
    sensor, v = _crowded(seed=3, n=200)
    nodes_x, nodes_y = sensor.project(v @ np.eye(3).T)
    windows, _ = make_windows(
        nodes_x[:, None], nodes_y[:, None], half_px=5.0,
        shape=(sensor.detector.rows, sensor.detector.columns), free=np.ones(len(v), bool),
    )  # fmt: skip
    parts = problem.split_parts(windows, 5)
    assert sorted(np.concatenate(parts).tolist()) == list(range(windows.n_groups))
    assert len(parts) >= 2  # lone stars apart from the blends
    one = [np.arange(windows.n_groups)]
    assert _values(parts, windows, 5) < _values(one, windows, 5)


@pytest.mark.parametrize("rate_deg_s", [0.0, 0.5])
def test_the_fit_does_not_depend_on_the_parts(monkeypatch, rate_deg_s):
    """The same frame fitted on parts and on one grid: the same optimum (sums reordered only).

    The likelihood is a sum over groups, so splitting them changes the order of floating-point
    sums and nothing else: attitudes agree to 1e-9 px, fluxes and chi-square to 1e-9 relative
    (a few hundred ulps of sums over ~10^4 pixels, well above 1e-16, far below any noise).
    The rate about the boresight draws streaks of lengths that grow with the radius: many box
    sizes.
    """
    sensor, v = _crowded(seed=7, n=200)
    det = sensor.detector
    truth = Rotation.from_rotvec([1e-4, -2e-4, 3e-4])
    image, kept, fluxes = model_image(sensor, v, truth, (3e3, 3e4), background_e=60.0)
    noisy = image + np.random.default_rng(1).standard_normal(image.shape) * np.sqrt(image + 25.0)
    counts = noisy * det.gain_counts_per_e + det.bias_counts
    rate = np.radians([0.0, 0.0, rate_deg_s]) if rate_deg_s else np.zeros(3)
    kw = {"vectors": v[kept], "rate_rad_s": rate, "fluxes_e": fluxes, "fit_width": True}
    parts = fit_windows(counts, sensor, truth, **kw)
    monkeypatch.setattr(problem, "MAX_PARTS", 1)
    whole = fit_windows(counts, sensor, truth, **kw)
    f = sensor.focal_length_px
    assert (parts.rotation * whole.rotation.inv()).magnitude() * f < 1e-9
    np.testing.assert_allclose(parts.fluxes_e, whole.fluxes_e, rtol=1e-9)
    assert parts.chi2 == pytest.approx(whole.chi2, rel=1e-9)
    assert parts.n_pixels == whole.n_pixels and parts.iterations == whole.iterations
    np.testing.assert_allclose(parts.covariance, whole.covariance, rtol=1e-8)
