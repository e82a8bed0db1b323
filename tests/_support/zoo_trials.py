"""The sensor zoo's designs and their Monte Carlo frames, drawn as the datasheet draws them.

Tests of frames the zoo found (``bench/zoo.py``): trial ``k`` of an ``n``-frame run is
rendered from the same seed stream as :func:`starsense.analysis.montecarlo.montecarlo`'s, so
a frame quoted from a run is that frame, bit for bit.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

from starsense.analysis.inputs import at_epoch, completed_sky
from starsense.catalog import load_catalog
from starsense.geometry.sampling import random_attitudes
from starsense.render.scene import render_frame
from starsense.solve import Solver
from starsense.units import DEG

_PATH = Path(__file__).resolve().parents[2] / "bench" / "zoo.py"
_spec = importlib.util.spec_from_file_location("starsense_bench_zoo", _PATH)
zoo = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(zoo)


def zoo_sensor(index: int, seed: int = 23):
    """Return design ``index`` of the zoo of 40 drawn with ``seed``."""
    name, params = zoo.zoo_designs(40, seed)[index]
    return zoo.make_sensor(name, **params)


def zoo_trial(index: int, *, seed: int, n_trials: int, trial: int, rate_deg_s: float = 0.0,
              **render):  # fmt: skip
    """Return ``(sensor, solver, truth, frame)``: trial ``trial`` of an ``n_trials`` run.

    The design is ``zoo_sensor(index, seed)``, the run's seed ``seed`` (the zoo's), its body
    rate ``rate_deg_s`` about a random axis across the boresight; ``render`` goes on to
    :func:`~starsense.render.scene.render_frame` (``model=``).
    """
    sensor = zoo_sensor(index, seed)
    catalog = load_catalog("hipparcos")
    solver = Solver(sensor=sensor, background="known", centroid_sigma_px="snr")
    sky = at_epoch(completed_sky(catalog, solver.catalog), solver.catalog.epoch_yr)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(n_trials)[trial])
    truth = random_attitudes(1, rng)[0]
    phi = rng.uniform(0, 2 * np.pi)
    rate = rate_deg_s * DEG * np.array([math.cos(phi), math.sin(phi), 0.0])
    frame = render_frame(sensor, truth, sky, rate_rad_s=rate, rng=rng, keep_expected=False,
                         fast_noise=True, **render)  # fmt: skip
    return sensor, solver, truth, frame
