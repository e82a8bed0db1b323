"""A long faint streak's pieces are one star's: joined at the streak's middle, it is identified."""

from __future__ import annotations

import numpy as np
import pytest
from zoo_trials import zoo_trial

from starsense.geometry.attitude import angular_separation, boresight, small_rotation_angles
from starsense.solve import streak_pieces
from starsense.units import ARCSEC


@pytest.mark.slow
def test_the_pieces_of_long_faint_streaks_are_joined_at_their_stars_middles(monkeypatch):
    """Design 21 of the tuning zoo (9 deg on 2624 x 1968 px, PSF sigma 0.52 px, 0.92 s) at
    1 deg/s: streaks of 266 px, one pixel wide, which the noise breaks into pieces 8-30 px
    long, each centroided up to 130 px from its star's mid-exposure place; but for the three
    brightest, no star was whole and the frame did not identify (``no_match``). The pieces
    the brightest streaks' rate lays on one streak are one detection, centred over the capsule
    the rate draws there: within 3 px of the star's place (the PSF and a pixel at each end,
    against a streak of 266 px), and the frame solves, right, within 4 of its sigma per axis (a
    4-sigma excursion of one of three axes has probability 2e-4)."""
    _, solver, truth, frame = zoo_trial(
        21, seed=23, n_trials=12, trial=2, rate_deg_s=1.0, model="reed"
    )
    raw = solver.detector(frame.image)
    groups = []
    grouped = streak_pieces._streak_groups

    def keep(det, streaks, *, width):
        out = grouped(det, streaks, width=width)
        groups.extend(out)
        return out

    monkeypatch.setattr(streak_pieces, "_streak_groups", keep)
    joined = streak_pieces.joined_pieces(solver, frame.image, raw)
    st = frame.truth.stars
    start = np.column_stack([st.x_start, st.y_start])
    end = np.column_stack([st.x_end, st.y_end])
    rows, cols = frame.image.shape
    on = np.all((start >= 0) & (start < [cols, rows]) & (end >= 0) & (end < [cols, rows]), axis=1)
    whole = [g for g in groups if len(g) > 1]
    checked = 0
    for g in whole:
        light = raw.integrated_counts[g].sum()
        i = int(np.flatnonzero(np.isclose(joined.integrated_counts, light))[0])
        star = _star_of(np.column_stack([raw.x[g], raw.y[g]]), start, end)
        if not on[star]:  # a streak run off the frame: its middle is not on it
            continue
        off = np.hypot(joined.x[i] - st.x_mid[star], joined.y[i] - st.y_mid[star])
        pieces = np.hypot(raw.x[g] - st.x_mid[star], raw.y[g] - st.y_mid[star])
        assert off < 3.0, (off, pieces)
        checked += pieces.max() > 30.0  # pieces far along the streak, joined
    assert checked >= 5, checked

    sol = solver(frame.image)
    assert sol.solved, sol.status
    assert angular_separation(boresight(truth), boresight(sol.rotation)) < 60.0 * ARCSEC
    z = small_rotation_angles(truth, sol.rotation) / np.asarray(sol.sigma_rad)
    assert np.all(np.abs(z) < 4.0), np.round(z, 2)


def _star_of(pieces, start, end) -> int:
    """Return the star whose streak (start to end) passes nearest the pieces (their mean)."""
    d = end - start
    t = np.clip(np.einsum("ij,ij->i", pieces.mean(axis=0) - start, d) / np.einsum("ij,ij->i", d, d),
                0.0, 1.0)  # fmt: skip
    near = start + t[:, None] * d
    return int(np.argmin(np.hypot(*(near - pieces.mean(axis=0)).T)))
