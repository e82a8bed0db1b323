"""The forward model's compiled kernel (``starsense.model._modelc``) against its NumPy form.

The NumPy forms (``windows.evaluate`` without the kernel, ``fit._normal_equations``' einsums)
are the reference. The kernel evaluates the same closed forms (erf and exp of the same
arguments) and sums the same terms in another order, so the two agree to rounding: 1e-12 of
the largest entry (float64 sums of ~10^2-10^4 terms of one sign each carry ~1e-14 relative
error; the margin covers libm's erf against SciPy's, both within a few ulp).
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import starsense._workspace as workspace
import starsense.model.fit as fit_module
import starsense.model.windows as windows_module
from starsense.model.fit import fit_windows
from starsense.model.psf import pixel_psf
from starsense.model.tracks import node_positions, time_nodes
from starsense.model.windows import evaluate, make_windows
from starsense.sensor import load_sensor
from starsense.sensor.psf_spec import PSFSpec

pytestmark = pytest.mark.skipif(
    windows_module._modelc is None, reason="the compiled model kernel is not built here"
)

RTOL = 1e-12  # module docstring


def _scene(seed, n=40):
    """Stars crowded enough that boxes overlap (groups of several, fixed neighbours)."""
    sensor = load_sensor("esa_blackfly")
    rng = np.random.default_rng(seed)
    det = sensor.detector
    # a cluster in one corner and some spread: blends, neighbours and boxes cut by the edge
    x = np.r_[rng.uniform(-3, 60, n // 2), rng.uniform(0, det.columns, n - n // 2)]
    y = np.r_[rng.uniform(-3, 60, n // 2), rng.uniform(0, det.rows, n - n // 2)]
    v = sensor.unproject(x, y)
    free = rng.random(n) < 0.6
    psf = pixel_psf(PSFSpec(kind="gaussian"), rng.uniform(0.6, 2.0))
    frac, wts = time_nodes(0.0, psf.sigma_px)
    rot = Rotation.from_rotvec(rng.normal(0, 1e-4, 3))
    nodes = node_positions(sensor, v, rot, rate_rad_s=np.zeros(3),
                           exposure_s=sensor.exposure_s, fractions=frac, weights=wts)  # fmt: skip
    windows, kept = make_windows(nodes.x, nodes.y, half_px=3.5 * psf.sigma_px + 1.0,
                                 shape=(det.rows, det.columns), free=free)  # fmt: skip
    nodes = node_positions(sensor, v[kept], rot, rate_rad_s=np.zeros(3),
                           exposure_s=sensor.exposure_s, fractions=frac, weights=wts)  # fmt: skip
    fluxes = rng.uniform(100.0, 5e4, len(kept))
    return sensor, psf, nodes, windows, fluxes


def _numpy_evaluate(monkeypatch, *args, **kwargs):
    with monkeypatch.context() as m:
        m.setattr(windows_module, "_modelc", None)
        return evaluate(*args, **kwargs)


def _close(a, b):
    scale = max(np.abs(b).max(), 1e-300)
    assert a.shape == b.shape
    assert np.abs(a - b).max() <= RTOL * scale


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize(("gradient", "width"), [(True, False), (True, True), (False, False)])
def test_compiled_evaluate_is_the_numpy_form(monkeypatch, seed, gradient, width):
    _sensor, psf, nodes, windows, fluxes = _scene(seed)
    assert windows.n_slots >= 2 and (windows.pair_slot < 0).any()  # blends and given light
    got = evaluate(windows, psf, nodes, fluxes=fluxes, gradient=gradient, width=width)
    ref = _numpy_evaluate(monkeypatch, windows, psf, nodes, fluxes=fluxes, gradient=gradient,
                          width=width)  # fmt: skip
    _close(got.templates, ref.templates)
    _close(got.fixed, ref.fixed)
    if gradient:
        _close(got.jacobian, ref.jacobian)
    else:
        assert got.jacobian is None and ref.jacobian is None


def test_evaluate_into_given_arrays_twice(monkeypatch):
    """Arrays reused by a fit's next step hold that step's model, not the sum of both."""
    _sensor, psf, nodes, windows, fluxes = _scene(4)
    g, m, (h, w) = windows.n_groups, windows.n_slots, windows.shape
    out = (np.zeros((g, m + 1, h, w)), np.zeros((g, h, w)), np.zeros((g, 4, h, w)))
    evaluate(windows, psf, nodes, fluxes=2.0 * fluxes, width=True, out=out)
    got = evaluate(windows, psf, nodes, fluxes=fluxes, width=True, out=out)
    ref = _numpy_evaluate(monkeypatch, windows, psf, nodes, fluxes=fluxes, width=True)
    _close(got.templates, ref.templates)
    _close(out[0][:, :m], ref.templates)
    _close(got.fixed, ref.fixed)
    _close(got.jacobian, ref.jacobian)


@pytest.mark.parametrize("seed", [5, 6])
def test_compiled_normal_equations_are_the_einsums(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    g, m, p, n = 7, 3, 4, 60
    lin = rng.normal(size=(g, m, n)) * (rng.random((g, m, n)) < 0.7)  # zeros as padding makes
    jac = rng.normal(size=(g, p, n))
    weight = rng.uniform(0.0, 2.0, (g, n)) * (rng.random((g, n)) < 0.8)  # unused pixels
    resid = rng.normal(size=(g, n))
    got = fit_module._normal_equations(lin, jac, weight, resid)
    with monkeypatch.context() as mp:
        mp.setattr(fit_module, "_modelc", None)
        ref = fit_module._normal_equations(lin, jac, weight, resid)
    for a, b in zip(got, ref, strict=True):
        _close(a, b)


def test_fits_in_turn_reuse_the_buffer_without_carrying_anything(monkeypatch):
    """Two fits in one thread (the second on the first's buffer) are the fits made apart."""
    sensor, psf, nodes, windows, fluxes = _scene(7, n=12)
    det = sensor.detector
    ev = evaluate(windows, psf, nodes, fluxes=fluxes, gradient=False)
    image = np.full((det.rows, det.columns), 40.0 * det.gain_counts_per_e + det.bias_counts)
    slots = np.zeros((windows.n_groups, windows.n_slots))
    free = windows.slot >= 0
    slots[windows.group[free], windows.slot[free]] = fluxes[free]
    light = np.einsum("gmhw,gm->ghw", ev.templates, slots) + ev.fixed
    for k in range(windows.n_groups):
        r0, c0 = windows.row0[k], windows.col0[k]
        rr = slice(max(r0, 0), min(r0 + windows.shape[0], det.rows))
        cc = slice(max(c0, 0), min(c0 + windows.shape[1], det.columns))
        local = (slice(rr.start - r0, rr.stop - r0), slice(cc.start - c0, cc.stop - c0))
        image[rr, cc] += light[k][local] * windows.on[k][local] * det.gain_counts_per_e
    v = sensor.unproject(nodes.x[:, 0], nodes.y[:, 0])
    start = Rotation.from_rotvec([0.0, 0.0, 2e-4])
    kw = {"vectors": v[free], "psf": psf, "fit_width": True}
    first = fit_windows(image, sensor, start, **kw)
    again = fit_windows(image, sensor, start, **kw)  # on the first's work buffer
    with monkeypatch.context() as mp:
        mp.setattr(workspace, "_LOCAL", threading.local())  # no work buffer yet
        apart = fit_windows(image, sensor, start, **kw)
    for fit in (first, again):
        np.testing.assert_array_equal(fit.rotation.as_quat(), apart.rotation.as_quat())
        np.testing.assert_array_equal(fit.covariance, apart.covariance)
        assert fit.chi2 == apart.chi2 and fit.iterations == apart.iterations
