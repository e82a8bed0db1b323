"""The solver's compiled Wahba fit against the estimator it stands for (SVD, scipy)."""

from __future__ import annotations

import numpy as np
import pytest
from attitude_fields import ARCSEC, add_noise, star_field
from scipy.spatial.transform import Rotation

from starsense.attitude.estimate import estimate_attitude
from starsense.attitude.solution import AttitudeSolution
from starsense.errors import SingularGeometryError
from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.attitude_fit import kernel_fit


@pytest.mark.parametrize("seed", range(20))
def test_kernel_fit_is_the_svd_estimator_to_rounding(seed):
    rng = np.random.default_rng(seed)
    n = 3 + seed
    attitude = Rotation.random(random_state=rng)
    b_true = star_field(rng, n, 15.0)
    sigma = rng.uniform(1.0, 30.0, n) * ARCSEC
    body = add_noise(rng, b_true, sigma)
    ref = attitude.inv().apply(b_true)
    want = estimate_attitude(body, ref, sigma, method="svd")
    got = kernel_fit(body, ref, sigma)
    assert got.method == "svd" and got.n_stars == n
    # the attitude: Davenport's eigenvector against LAPACK's SVD, ~1e-15 rad apart times the
    # conditioning of weights spread 900-fold; 1e-6 of the attitude's own sigma bounds it
    own = np.sqrt(np.diag(want.covariance_rad2))
    assert np.all(np.abs(small_rotation_angles(want.rotation, got.rotation)) < 1e-6 * own)
    # the matrix given, and the Rotation built from it when read: one attitude (~1e-16)
    np.testing.assert_allclose(got.rotation.as_matrix(), got.matrix, rtol=0, atol=1e-15)
    # the inverse Fisher matrix of the same vectors: the same sums in another order
    np.testing.assert_allclose(got.covariance_rad2, want.covariance_rad2, rtol=1e-9)
    # residuals from the chord (2 asin(c / 2)) against atan2(|b x Ar|, b . Ar): equal angles,
    # each exact to ~1e-16 rad, the attitudes' difference adding ~1e-6 sigma (<= 3e-11 rad)
    np.testing.assert_allclose(got.residuals_rad, want.residuals_rad, rtol=0, atol=1e-10)
    assert got.residual_rms_rad == pytest.approx(want.residual_rms_rad, rel=1e-6)
    assert got.loss == pytest.approx(want.loss, rel=1e-6)


def test_stars_that_fix_no_attitude_raise_the_estimators_error():
    # two stars in the same direction leave the rotation about it free: singular Fisher matrix
    body = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    with pytest.raises(SingularGeometryError, match="singular geometry"):
        kernel_fit(body, body, np.full(3, 1e-5))


def test_the_fit_stored_at_once_is_the_dataclass_and_replaced_keeps_it():
    rng = np.random.default_rng(5)
    attitude = Rotation.random(random_state=rng)
    b_true = star_field(rng, 12, 15.0)
    sigma = np.full(12, 5.0 * ARCSEC)
    body = add_noise(rng, b_true, sigma)
    got = kernel_fit(body, attitude.inv().apply(b_true), sigma)
    made = AttitudeSolution(
        rotation=got.matrix,
        covariance_rad2=got.covariance_rad2,
        residual_rms_rad=got.residual_rms_rad,
        residuals_rad=got.residuals_rad,
        method=got.method,
        n_stars=got.n_stars,
        loss=got.loss,
    )
    assert made.__dict__.keys() == got.__dict__.keys()
    for name, value in made.__dict__.items():
        assert np.array_equal(got.__dict__[name], value), name
    # replaced without a new rotation: the fields copied, the matrix still unbuilt
    scaled = got.replaced(covariance_rad2=2.0 * got.covariance_rad2)
    assert scaled.__dict__["_rotation"] is None and scaled.matrix is got.matrix
    np.testing.assert_array_equal(scaled.covariance_rad2, 2.0 * got.covariance_rad2)
    assert (scaled.loss, scaled.n_stars, scaled.notes) == (got.loss, got.n_stars, got.notes)
    # with one, or a name that is no field: as dataclasses.replace (which refuses the name)
    turned = got.replaced(rotation=Rotation.identity())
    np.testing.assert_array_equal(turned.matrix, np.eye(3))
    with pytest.raises(TypeError):
        got.replaced(sigma=1.0)
    with pytest.raises(TypeError):
        AttitudeSolution.of_fit(got.matrix, rotation=got.matrix)
