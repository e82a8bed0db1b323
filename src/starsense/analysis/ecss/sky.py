"""The stars of the datasheet's sky, per attitude, and their per-axis temporal noise.

The statement is computed on the datasheet's own sky statistics: the same catalogue (completed
with the solver's database, :func:`starsense.analysis.inputs.completed_sky`), the same
quasi-uniform attitudes (:func:`starsense.analysis.availability.pointings.sky_attitudes`, its
seed), the same stars (those the model fit holds,
:mod:`starsense.analysis.datasheet.stars`) and the same star model
(:class:`starsense.analysis.datasheet.predict.StarModel`). Per attitude its X and Y are
then the datasheet's cross split in two (``X^2 + Y^2 = 2 cross^2``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from starsense.analysis.availability.pointings import sky_attitudes
from starsense.analysis.datasheet.field import FieldStarsCam, field_stars_cam
from starsense.analysis.datasheet.model_noise import model_fisher_at_rate
from starsense.analysis.datasheet.predict import StarModel
from starsense.analysis.datasheet.stars import FittedStars, detection_chance, fitted_stars
from starsense.analysis.ecss.axes import fisher_axes, propagated_axes
from starsense.analysis.inputs import completed_sky
from starsense.errors import InputError
from starsense.identify.hashing import MIN_SOLVING_STARS
from starsense.solve.solver import Solver
from starsense.units import RAD_TO_DEG

__all__ = ["MAX_RATE_ATTITUDES", "SkyStars", "chance_at_least", "sky_stars"]

#: the most attitudes the noise at a rate is computed over (its sky median to a few per cent)
MAX_RATE_ATTITUDES = 200
#: the child stream of the root seed the rate directions are drawn from
_RATE_STREAM = 0xEC55
#: the golden ratio's fractional part: the most even sequence of directions on a circle
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True)
class SkyStars:
    """The datasheet's attitudes and the stars the solver fits in each.

    Attributes
    ----------
    model : StarModel
        Magnitude -> per-star sigmas (the datasheet's).
    fov : RectangularFov
        The sensor's field.
    matrices : ndarray (M, 3, 3)
        Attitudes, ICRS -> camera.
    stars : FittedStars
        The stars the solver may fit, with their chances of detection.
    vectors, magnitudes, presence : ndarray (N, 3), (N,), (N,)
        Those it may fit at rest (ICRS, V) and the chance each is in the fit.
    pairs : FieldStarsCam
        Those in the field of each attitude.
    weights : ndarray (P,)
        The solver's weight of each pair, rad^-2.
    seed : int
        The datasheet's root seed (the rate directions are drawn from it).
    catalog : Catalog
        The catalogue given (before the database's stars are added).
    """

    model: StarModel
    fov: object
    matrices: np.ndarray
    stars: FittedStars
    vectors: np.ndarray
    magnitudes: np.ndarray
    presence: np.ndarray
    pairs: FieldStarsCam
    weights: np.ndarray
    seed: int
    catalog: object

    @property
    def rate_stride(self) -> int:
        """Return the stride through the attitudes of the noise at a rate (at most 200 kept)."""
        return max(1, math.ceil(len(self.matrices) / MAX_RATE_ATTITUDES))

    def propagated(self, kind: str) -> np.ndarray:
        """Return the X, Y, Z error (M, 3), rad, of a per-star error kind of the star model."""
        mags = self.magnitudes[self.pairs.star]
        sigma = self.model.star_sigmas_rad(mags, self.pairs.v_cam[:, 2], kind)
        error = np.where(np.isfinite(sigma), sigma, 0.0)
        return propagated_axes(
            self.pairs,
            self.weights,
            error,
            presence=self.presence[self.pairs.star],
            shape=self.model.star_shape(mags),
            efficient=kind == "nea" and self.model.refine == "model",
        )

    def solving(self, rate_rad_s: float) -> np.ndarray:
        """Return each attitude's chance of a solution at ``rate_rad_s`` (M,).

        The chance that at least :data:`~starsense.identify.hashing.MIN_SOLVING_STARS` of the
        field's stars are detected, each with its own chance at the rate (a Poisson-binomial
        tail: :func:`chance_at_least`; a star the model fit holds but the detector misses
        identifies nothing); the datasheet's availability counts the same stars against the
        same number, each in or out at its limiting magnitude. The statement describes the
        attitudes a sensor outputs: its values over the sky are weighted by this chance.
        """
        stars = self.stars
        rest = stars.presence(0.0)
        # detected, not fitted: the model fit also holds stars too faint to detect, which
        # identify nothing (counted, every attitude of a sensor that solves 70 % of the sky
        # read as solving)
        seen = detection_chance(stars.slew, stars.magnitudes, rate_rad_s)
        at_rate = np.where(stars.held, seen, 0.0)[rest > 0.0]  # aligned with self.vectors
        return chance_at_least(
            self.pairs.point, at_rate[self.pairs.star], self.pairs.n_pointings, k=MIN_SOLVING_STARS
        )

    def temporal_at_rate(self, rate_rad_s: float) -> np.ndarray:
        """Return the model fit's X, Y, Z noise (M, 3), rad, at a cross-boresight body rate.

        Each attitude turns about a cross-boresight axis at its own angle, spread evenly over
        the circle (the datasheet's Monte Carlo draws it at random,
        :func:`starsense.analysis.montecarlo.montecarlo`), from the seed;
        each star counts when the fit holds it at the rate. A smeared star's
        information is computed star by star (about a millisecond each), so the attitudes are
        thinned to at most :data:`MAX_RATE_ATTITUDES`, every :attr:`rate_stride`-th of the
        lattice (which spirals from pole to pole: a stride keeps it spread over the sky).

        Returns
        -------
        ndarray (K, 3)
            rad, over the ``K`` attitudes kept.

        Raises
        ------
        InputError
            Past the slew tolerance run's top rate (no chance of detection known there).
        """
        top = float(np.max(self.stars.slew.rates_rad_s))
        if rate_rad_s > top * (1.0 + 1e-9):
            raise InputError(
                f"rate {rate_rad_s * RAD_TO_DEG:g} deg/s is past the slew tolerance run's top "
                f"rate {top * RAD_TO_DEG:.3g} deg/s; give rates up to it"
            )
        mats = self.matrices[:: self.rate_stride]
        m = len(mats)
        # the directions stratified over the circle (a golden-ratio sequence from a random
        # start): a median over a few hundred attitudes is not left to where the draws fall
        start = np.random.default_rng([self.seed, _RATE_STREAM]).uniform()
        phi = 2.0 * math.pi * np.mod(start + np.arange(m) * _GOLDEN, 1.0)
        rates = rate_rad_s * np.column_stack([np.cos(phi), np.sin(phi), np.zeros(m)])
        vectors, mags, presence, _ = self.stars.at(rate_rad_s)
        fisher = model_fisher_at_rate(
            self.model,
            self.fov,
            mats,
            rates_rad_s=rates,
            vectors=vectors,
            magnitudes=mags,
            presence=presence,
        )
        return fisher_axes(fisher)


def chance_at_least(group, chance, n_groups: int, *, k: int) -> np.ndarray:
    """Return, per group, the chance that at least ``k`` of its independent events happen.

    Parameters
    ----------
    group : ndarray (P,) of int
        The group of each event, in [0, n_groups).
    chance : ndarray (P,)
        Each event's probability.
    n_groups : int
    k : int
        >= 1.

    Returns
    -------
    ndarray (n_groups,)
        ``P(N >= k)``, ``N`` the number of a group's events that happen (Poisson-binomial).
    """
    group = np.asarray(group, dtype=np.intp)
    chance = np.clip(np.asarray(chance, dtype=float), 0.0, 1.0)
    order = np.argsort(group, kind="stable")
    g, q = group[order], chance[order]
    starts = np.searchsorted(g, np.arange(n_groups))
    rank = np.arange(len(g)) - starts[g]  # the event's place within its group
    dist = np.zeros((n_groups, k + 1))  # P(N = 0..k-1), and P(N >= k) in the last column
    dist[:, 0] = 1.0
    for r in range(int(rank.max(initial=-1)) + 1):
        sel = rank == r
        rows, p = g[sel], q[sel][:, None]
        d = dist[rows]
        moved = d * p
        d = d * (1.0 - p)
        d[:, 1:] += moved[:, :-1]
        d[:, -1] += moved[:, -1]  # at least k stays at least k
        dist[rows] = d
    return dist[:, -1]


def sky_stars(sensor, catalog, settings, *, limit_mag: float, slew) -> SkyStars:
    """Return the datasheet's sky of ``sensor`` (module docstring).

    Parameters
    ----------
    sensor : Sensor
    catalog : Catalog
        The datasheet's catalogue (V magnitudes).
    settings : DatasheetSettings
        Its attitudes (``n_orientations``, ``seed``), model and solver (``refine``).
    limit_mag : float
        The datasheet's limiting magnitude at rest, V.
    slew : SlewResult
        The datasheet's slew tolerance run (each star's chance of detection).

    Returns
    -------
    SkyStars
    """
    cat = completed_sky(catalog, Solver(sensor=sensor).catalog)
    stars = fitted_stars(
        cat, sensor, slew=slew, limit_mag=limit_mag, refine=settings.refine, model=settings.model
    )
    vectors, mags, presence, _ = stars.at(0.0)  # as the datasheet
    model = StarModel.build(
        sensor,
        model=settings.model,
        bright_mag=float(np.min(mags)),
        faint_mag=max(limit_mag, float(np.max(mags, initial=limit_mag))),
        refine=settings.refine,
    )
    _, att = sky_attitudes(settings.n_orientations, None, settings.seed)
    mats = att.as_matrix()
    fov = sensor.fov()
    pairs = field_stars_cam(fov, mats, vectors)
    sigma_w = model.star_sigmas_rad(mags[pairs.star], pairs.v_cam[:, 2], "weight")
    weights = 1.0 / sigma_w**2
    return SkyStars(
        model, fov, mats, stars, vectors, mags, presence, pairs, weights, settings.seed, catalog
    )
