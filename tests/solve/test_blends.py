"""Close doubles: the photocentre replaces the matched star's direction."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from starsense.solve.blends import blend_radius_px, photocentres
from starsense.units import ARCSEC


def test_photocentre_of_equal_and_unequal_pairs():
    base = np.array([0.0, 0.0, 1.0])
    off = np.array([20 * ARCSEC, 0.0, 1.0])
    off /= np.linalg.norm(off)
    far = np.array([0.0, 1.0, 0.0])
    v = np.stack([base, off, far])
    tree = cKDTree(v)
    # equal pair: the midpoint (to first order in the 20 arcsec separation)
    out = photocentres(v, np.array([5.0, 5.0, 5.0]), tree, index=[0, 2], radius_rad=60 * ARCSEC)
    assert np.arctan2(out[0, 0], out[0, 2]) == pytest.approx(10 * ARCSEC, rel=1e-6)
    np.testing.assert_array_equal(out[1], far)  # no neighbour: unchanged
    # a companion 2.5 mag fainter carries 1/11 of the light: 20/11 arcsec towards it
    out = photocentres(v, np.array([5.0, 7.5, 5.0]), tree, index=[0], radius_rad=60 * ARCSEC)
    assert np.arctan2(out[0, 0], out[0, 2]) == pytest.approx(20 * ARCSEC / 11, rel=1e-3)
    # outside the radius: unchanged
    np.testing.assert_array_equal(
        photocentres(v, np.ones(3), tree, index=[0], radius_rad=10 * ARCSEC)[0], base
    )


def test_blend_radius_grows_with_the_psf():
    # two equal Gaussians are single-peaked below 2 sigma apart
    assert blend_radius_px(1.5) == pytest.approx(3.5)
    assert blend_radius_px(0.8) > 2 * 0.8
