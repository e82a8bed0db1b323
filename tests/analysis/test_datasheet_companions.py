"""Merged companions in the catalogue term: a double the model fit draws as one star."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.special import erf

from starsense.analysis.datasheet.catalogue import merged_pull_rad
from starsense.catalog import Catalog
from starsense.sensor import load_sensor
from starsense.solve.refine import MERGED_PX


def _pixel_gaussian(x0, y0, sigma, n=21):
    """A Gaussian integrated over each pixel of an n x n grid centred on 0 (erf differences)."""
    edges = np.arange(n + 1) - n / 2.0
    gx = 0.5 * np.diff(erf((edges - x0) / (math.sqrt(2.0) * sigma)))
    gy = 0.5 * np.diff(erf((edges - y0) / (math.sqrt(2.0) * sigma)))
    return gy[:, None] * gx[None, :]


def _formula(f, d, sigma):
    s2 = sigma * sigma + 1.0 / 12.0  # the pixel-integrated profile's variance
    fw = f * math.exp(-d * d / (4.0 * s2))
    return fw * d / (1.0 + fw)


def test_the_pull_is_what_a_least_squares_fit_of_the_star_alone_finds():
    # independent computation: a star of sigma 1.2 px with a companion (flux ratio f, offset
    # d along x) drawn by erf differences, fitted by scipy's least squares with one star's
    # profile (position, flux, background free). The first-order pull f w d / (1 + f w) is
    # within 1-16 % of the fit's shift from a faint close companion (f 0.05 at 0.7 sigma)
    # to an equal one blended (f 1 at 0.5 px); 20 % allows the second order a 0.2 companion
    # at 2 sigma leaves
    sigma = 1.2
    for f, d in ((0.05, 1.8), (0.05, 0.84), (0.2, 2.4), (0.5, 0.3), (0.1, 3.6), (1.0, 0.5)):
        star = 1e4 * _pixel_gaussian(0.3, -0.2, sigma)
        img = star + 1e4 * f * _pixel_gaussian(0.3 + d, -0.2, sigma) + 10.0  # and a background

        def residual(p, img=img):
            return (p[2] * _pixel_gaussian(p[0], p[1], sigma) + p[3] - img).ravel()

        fit = least_squares(residual, [0.3, -0.2, 1e4, 10.0])
        assert abs(fit.x[1] + 0.2) < 1e-6  # along the companion only
        assert (fit.x[0] - 0.3) == pytest.approx(_formula(f, d, sigma), rel=0.2)


def test_companions_the_fit_merges_pull_the_stars_they_sit_beside():
    # a database of 50 stars and a rendering that also holds a companion 0.2 px from each of
    # the first ten (2 mag fainter: inside the fit's merge radius, drawn as part of the star),
    # and one 1.5 px from the eleventh (a neighbour the fit draws on its own): the first ten
    # are pulled by the formula's amount towards their companion, the others not
    sensor = load_sensor("st16")
    px = 1.0 / sensor.focal_length_px  # rad a pixel at the axis
    assert 0.2 < MERGED_PX < 1.5
    rng = np.random.default_rng(3)
    v = rng.normal(size=(50, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    east = np.cross([0.0, 0.0, 1.0], v)
    east /= np.linalg.norm(east, axis=1)[:, None]
    far = np.r_[np.full(10, 0.2), 1.5]
    comp = v[:11] + far[:, None] * px * east[:11]
    comp /= np.linalg.norm(comp, axis=1)[:, None]

    def cat(vec, mags, name):
        return Catalog.from_columns(
            name=name, source="test", epoch_yr=2000.0, ids=np.arange(len(vec)),
            ra_deg=np.degrees(np.arctan2(vec[:, 1], vec[:, 0])) % 360.0,
            dec_deg=np.degrees(np.arcsin(vec[:, 2])), mags={"V": mags},
        )  # fmt: skip

    mags = np.full(50, 5.0)
    database = cat(v, mags, "db")
    rendered = cat(np.vstack([v, comp]), np.r_[mags, np.full(11, 7.0)], "sky")
    pull = merged_pull_rad(rendered, database, sensor, max_mag=8.0)
    assert pull.shape == (61, 3)
    size = np.linalg.norm(pull, axis=1) / px
    want = _formula(10 ** (-0.8), 0.2, sensor.detector.psf_sigma_px)
    np.testing.assert_allclose(size[:10], want, rtol=1e-3)  # the plate scale off axis: < 1e-3
    assert np.all(np.einsum("ij,ij->i", pull[:10], east[:10]) > 0)  # towards the companion
    assert np.all(size[10:] < 1e-9)  # drawn on its own, alone, or the companions themselves
