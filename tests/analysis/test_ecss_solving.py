"""The statement over the attitudes that solve: chances of a solution, weighted sky statistics."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from starsense.analysis.ecss.confidence import mixture_bound, weighted_median
from starsense.analysis.ecss.sky import chance_at_least
from starsense.identify.hashing import MIN_SOLVING_STARS, PATTERN_STARS


def _enumerated(chances, k: int) -> float:
    """P(at least k of the independent events happen), by summing over every outcome."""
    total = 0.0
    for outcome in itertools.product((0, 1), repeat=len(chances)):
        if sum(outcome) >= k:
            total += np.prod([c if o else 1 - c for c, o in zip(chances, outcome, strict=True)])
    return float(total)


def test_chance_at_least_equals_the_enumeration_of_every_outcome():
    rng = np.random.default_rng(7)
    groups = rng.integers(0, 5, size=40)
    chances = rng.uniform(0.0, 1.0, size=40)
    got = chance_at_least(groups, chances, 6, k=MIN_SOLVING_STARS)
    for g in range(6):
        want = _enumerated(chances[groups == g], MIN_SOLVING_STARS)
        # the same sums in another order: equal to rounding
        assert got[g] == pytest.approx(want, abs=1e-12)
    assert got[5] == 0.0  # a group without events never has five


def test_chance_at_least_of_certain_events_counts_them():
    groups = np.repeat(np.arange(8), np.arange(8))  # group g holds g certain events
    got = chance_at_least(groups, np.ones(len(groups)), 8, k=MIN_SOLVING_STARS)
    assert got.tolist() == [float(g >= MIN_SOLVING_STARS) for g in range(8)]


def test_lost_in_space_needs_one_star_beyond_the_pattern():
    # with no match beyond the pattern's own stars nothing is evidence: the floor is one more
    from starsense.identify.verify import false_match_probability

    p = false_match_probability(
        PATTERN_STARS, PATTERN_STARS, n_hypothesis=PATTERN_STARS, p_single=1e-6
    )
    assert p == 1.0
    assert MIN_SOLVING_STARS == PATTERN_STARS + 1


def test_weights_are_repetitions():
    # an attitude of integer weight n counts as n attitudes: the same bound and median
    rng = np.random.default_rng(3)
    sigmas = rng.uniform(0.5, 4.0, size=9)
    n = rng.integers(0, 4, size=9)
    repeated = np.repeat(sigmas, n)
    for conf in (0.6826894921370859, 0.95, 0.9973):
        # both solved to the same tolerance by brentq: 1e-9 relative
        assert mixture_bound(sigmas, conf, n) == pytest.approx(
            mixture_bound(repeated, conf), rel=1e-9
        )
    odd = np.append(repeated, 10.0) if len(repeated) % 2 == 0 else repeated
    w = np.append(n, 1) if len(repeated) % 2 == 0 else n
    vals = np.append(sigmas, 10.0) if len(repeated) % 2 == 0 else sigmas
    assert weighted_median(vals, w) == float(np.median(odd))  # one middle value: exact


def test_unit_weights_change_nothing_and_zero_weights_leave_out():
    s = np.array([1.0, 2.0, np.nan, 5.0])
    assert mixture_bound(s, 0.9) == mixture_bound(s, 0.9, np.ones(4))
    assert mixture_bound(s, 0.9, [0, 0, 1, 1]) == pytest.approx(mixture_bound([5.0], 0.9), rel=1e-9)
    assert weighted_median(s) == float(np.nanmedian(s))
    assert weighted_median(s, [0, 0, 0, 0]) is None


@pytest.mark.slow
def test_the_chance_of_a_solution_is_the_monte_carlos_solved_fraction():
    # esa_blackfly at rest: a sparse field whose frames solve about 70 % of the sky. The model
    # fit also holds stars too faint to detect: counted as solving stars, every attitude read
    # as solving (a mean chance of 1.00, the statement's sky bounds then over the whole sky,
    # its poorer attitudes included). Detected stars give ~0.70 over the sky's attitudes; 200
    # frames of the datasheet's Monte Carlo at other random attitudes solve a binomial
    # fraction about it (sd 3.2 %): within 0.1 (3 sd), which the 1.00 of fitted stars is not
    from starsense.analysis.datasheet.sheet import DatasheetSettings, build_datasheet
    from starsense.analysis.ecss.sky import sky_stars
    from starsense.analysis.inputs import as_catalog
    from starsense.analysis.montecarlo import montecarlo
    from starsense.photometry.colour import with_johnson_from_gaia
    from starsense.sensor import load_sensor

    sensor = load_sensor("esa_blackfly")
    cat, _ = with_johnson_from_gaia(as_catalog(None))
    light = DatasheetSettings(n_trials=0, n_orientations=500, n_slew_trials=4)
    sheet = build_datasheet(sensor, cat, settings=light)
    sky = sky_stars(sensor, cat, light, limit_mag=sheet.limiting_magnitude, slew=sheet.slew)
    chance = float(np.mean(sky.solving(0.0)))
    run = montecarlo(sensor, n_trials=200, rng=20261207)
    solved = (run.n_solved - run.n_wrong) / run.n_trials
    assert abs(chance - solved) < 0.1, (chance, solved)
    fitted = sky.stars.presence(0.0)[sky.stars.presence(0.0) > 0.0][sky.pairs.star]
    every = chance_at_least(sky.pairs.point, fitted, sky.pairs.n_pointings, k=MIN_SOLVING_STARS)
    assert float(np.mean(every)) - solved > 0.1  # what counting the fitted stars would say
