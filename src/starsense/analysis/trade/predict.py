"""The fast prediction: everything the datasheet predicts for a design, without frames.

:func:`predict` is :func:`~starsense.analysis.datasheet.build_datasheet` with no rendered
frames (``n_trials=0``): the same models (the slew-tolerance renders of single-star stamps,
the centroid noise of single-star windows, the Fisher propagation over the sky's boresights),
evaluated only on what they need. The numbers are therefore the datasheet's own: the same
design and seed give the same predicted values in ``starsense datasheet``, ``starsense
trade``, the design page and this function; the datasheet adds the check on rendered frames.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from starsense.analysis.datasheet.sections import Datasheet
from starsense.analysis.datasheet.sheet import DatasheetSettings, build_datasheet
from starsense.analysis.inputs import as_catalog, as_sensor, root_seed
from starsense.errors import InputError
from starsense.units import DEG

__all__ = ["predict", "prediction_settings"]


def prediction_settings(
    *,
    rate_rad_s: float = 1.0 * DEG,
    rng: int | np.random.Generator | None = 0,
    n_orientations: int = 2000,
    model: str = "reed",
    n_slew_trials: int = 20,
) -> DatasheetSettings:
    """Return the datasheet settings of a prediction (no frames: ``n_trials=0``).

    Parameters
    ----------
    rate_rad_s : float
        The rate of the "at rate" rows, rad/s.
    rng : None, int or numpy.random.Generator
        Root seed (recorded).
    n_orientations : int
        Quasi-uniform boresights of the sky statistics.
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model.
    n_slew_trials : int
        Single-star renders per (magnitude, rate) of the slew-tolerance curve.

    Returns
    -------
    DatasheetSettings
    """
    return DatasheetSettings(
        n_trials=0,
        n_rate_trials=0,
        rate_rad_s=rate_rad_s,
        seed=root_seed(rng),
        n_orientations=n_orientations,
        n_slew_trials=n_slew_trials,
        model=model,
        slew_full_grid=False,  # the tolerance alone: the same numbers, fewer renders
    )


#: a keyword of :func:`predict` left out (its default comes from :func:`prediction_settings`)
_UNSET = object()


def predict(
    sensor,
    catalog=None,
    *,
    rate_rad_s=_UNSET,
    rng=_UNSET,
    n_orientations=_UNSET,
    model=_UNSET,
    n_slew_trials=_UNSET,
    settings: DatasheetSettings | None = None,
) -> Datasheet:
    """Return what the datasheet predicts for ``sensor``, without rendering frames.

    Limiting magnitude, stars in the field, NEA per axis over the sky (median, 95th
    percentile), the physical limit and NEA / limit, the slew-tolerance curve, availability at
    rest and under slew with the fastest rates that keep 50/90/99 %, and the error budget. The
    keywords are those of :func:`~starsense.analysis.datasheet.datasheet` that do not render
    frames, with the same defaults: ``predict(s, rng=1)`` predicts what ``datasheet(s, rng=1)``
    does.

    Parameters
    ----------
    sensor : Sensor, str or Path
        The design (object, preset name or sensor TOML file).
    catalog : Catalog, str or None
        The catalogue (None: the bundled Hipparcos).
    rate_rad_s : float
        The rate of the "at rate" rows, rad/s (default 1 deg/s).
    rng : None, int or numpy.random.Generator
        Root seed of every random step (default 0; recorded in ``settings.seed``).
    n_orientations : int
        Quasi-uniform boresights of the sky statistics (default 2000).
    model : {"reed", "liebe", "blackbody"}
        Sensitivity model (default "reed").
    n_slew_trials : int
        Single-star renders per (magnitude, rate) of the slew-tolerance curve (default 20).
    settings : DatasheetSettings, optional
        All of them at once (:func:`prediction_settings`), instead of the keywords above; any
        ``n_trials`` given is replaced by 0.

    Returns
    -------
    Datasheet
        Its ``monte_carlo`` sections hold ``frames = 0`` and no measured numbers.

    Raises
    ------
    InputError
        ``settings`` given together with one of the keywords it holds.
    """
    given = {
        k: v
        for k, v in (
            ("rate_rad_s", rate_rad_s),
            ("rng", rng),
            ("n_orientations", n_orientations),
            ("model", model),
            ("n_slew_trials", n_slew_trials),
        )
        if v is not _UNSET
    }
    if settings is not None and given:
        raise InputError(
            f"predict: give settings or {', '.join(given)}, not both (settings holds them)"
        )
    st = prediction_settings(**given) if settings is None else settings
    st = replace(st, n_trials=0, n_rate_trials=0)
    return build_datasheet(as_sensor(sensor), as_catalog(catalog), settings=st)
