"""Neighbours in a detection's window: the window's centre of gravity, and a frame it fixes."""

from __future__ import annotations

import numpy as np
import pytest
from photutils.centroids import centroid_com
from zoo_trials import zoo_trial

from starsense.geometry.attitude import small_rotation_angles
from starsense.render.psf import gaussian_stamp
from starsense.solve.box_blends import window_shifts_px


def _photutils_cog(sources, window, *, sigma, clip=None, power=1):
    """The window's centre of gravity by photutils on the renderer's own pixels."""
    r0, r1, c0, c1 = window
    plane = np.zeros((r1 - r0, c1 - c0))
    for x, y, f in sources:
        stamp, _, _ = gaussian_stamp(x, y, sigma_px=sigma, electrons=f, box=window)
        plane += stamp
    if clip is not None:
        plane = np.minimum(plane, clip)
    cx, cy = centroid_com(plane**power)
    return np.array([cx + c0, cy + r0])


@pytest.mark.parametrize(
    ("neighbour", "clip", "power"),
    [
        ((14.6, 21.3, 0.18), None, 1),  # the V 2.6 / V 4.5 pair: a fifth of the light, 3.6 px
        ((16.2, 17.1, 0.05), None, 2),  # a faint one at the window's edge, squared weights
        ((12.4, 22.9, 0.6), 2e-2, 1),  # a bright star clipped: its neighbour counts for more
        ((18.5, 24.0, 0.3), None, 1),  # outside the window, its PSF's tail inside
    ],
)
def test_window_shift_is_the_centre_of_gravity_of_the_rendered_window(neighbour, clip, power):
    """The model's shift equals photutils' centre of gravity of the same window rendered by
    the renderer (star and neighbour, less the star alone), to float rounding: both integrate
    the same Gaussian over the same pixels (1e-9 px is 1e6 times below any centroid noise)."""
    sigma, window = 1.06, (15, 26, 7, 17)
    star = (11.3, 20.2, 1.0)
    got = window_shifts_px(
        [0, 0],
        [star[:2], neighbour[:2]],
        [star[2], neighbour[2]],
        windows=[window],
        sigma_px=sigma,
        clip=clip,
        power=power,
    )[0]
    want = _photutils_cog([star, neighbour], window, sigma=sigma, clip=clip, power=power)
    want -= _photutils_cog([star], window, sigma=sigma, clip=clip, power=power)
    assert np.allclose(got, want, atol=1e-9), (got, want)
    assert np.hypot(*got) > 1e-3  # and the neighbour does move it


def test_several_windows_at_once_equal_each_alone():
    """Windows batched together (different sizes, different neighbour counts) give each
    window's shift as it is alone: the padding holds no light."""
    sigma = 1.5
    windows = np.array([[0, 9, 0, 9], [20, 41, 30, 38], [5, 12, 50, 70]])
    owner = [0, 0, 1, 1, 1, 2]
    xy = [[4.2, 4.9], [6.5, 3.0], [33.1, 30.2], [35.0, 27.5], [31.0, 36.0], [60.3, 8.1]]
    flux = [1.0, 0.4, 2.0, 0.7, 0.2, 1.0]
    together = window_shifts_px(owner, xy, flux, windows=windows, sigma_px=sigma)
    alone = [
        window_shifts_px(
            [0] * owner.count(k),
            [p for p, o in zip(xy, owner, strict=True) if o == k],
            [f for f, o in zip(flux, owner, strict=True) if o == k],
            windows=windows[k : k + 1],
            sigma_px=sigma,
        )[0]
        for k in range(3)
    ]
    assert np.allclose(together, alone, atol=1e-12)
    assert np.all(together[2] == 0.0)  # a star with no neighbour does not move


@pytest.mark.slow
def test_a_bright_pair_lit_as_one_region_is_referenced_to_its_window():
    """Trial 1607 of 1834 of a 12.2 deg design (1024 px of 12.8 um, PSF sigma 1.06 px,
    10-bit) at rest: a V 2.56 star and a V 4.45 neighbour 3.6 px away, past the 2.6 px of the
    close-double photocentre, light one region whose centroid is 0.6 px off the bright star;
    that star is 250 px from the others, and the roll was 375 arcsec off, 9.6 times its
    prediction (5.9 of its own sigma). Referenced to where its window's centre of gravity
    lands with the neighbour, the attitude lies within 3 of its sigma on every axis (a right
    solution's error is Gaussian in its sigma: 3 sigma on any of three axes is exceeded by
    chance in 0.8 % of frames)."""
    _, solver, truth, frame = zoo_trial(19, seed=23, n_trials=1834, trial=1607)
    sol = solver(frame.image)
    assert sol.solved
    z = small_rotation_angles(truth, sol.rotation) / np.asarray(sol.sigma_rad)
    assert np.all(np.abs(z) < 3.0), np.round(z, 2)
