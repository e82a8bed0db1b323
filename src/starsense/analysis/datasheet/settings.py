"""How a datasheet is computed: :class:`DatasheetSettings` (all reported in its JSON)."""

from __future__ import annotations

from dataclasses import dataclass

from starsense.errors import InputError
from starsense.units import DEG

__all__ = ["DatasheetSettings"]


@dataclass(frozen=True, kw_only=True)
class DatasheetSettings:
    """How the datasheet is computed (all reported in its JSON ``settings``).

    Attributes
    ----------
    n_trials : int
        Monte Carlo frames at rest, and again at ``rate_rad_s`` (JSON ``trials``); 0 gives
        the prediction alone (no frames rendered).
    rate_rad_s : float
        Cross-axis rate of the second Monte Carlo, rad/s.
    seed : int
        Root seed of every random step.
    n_orientations : int
        Quasi-uniform boresights of the sky statistics.
    n_slew_trials : int
        Renders per (magnitude, rate) of the slew-tolerance Monte Carlo (JSON ``slew_trials``).
    model : str
        Sensitivity model (magnitude -> photo-electrons).
    n_rate_trials : int or None
        Frames of the run at ``rate_rad_s`` (None: ``n_trials``).
    slew_full_grid : bool
        Simulate every (magnitude, rate) cell of the slew run (the report plots its Fig. 9
        intensities); False stops each magnitude at the rate where it is lost. Both give the
        same numbers in the datasheet (limit, tolerance, ``m_t(w)``, availability).
    refine : {"model", "cog"}
        The solver predicted and checked: "model" (the default :class:`~starsense.solve.
        Solver`, its forward-model fit: the NEA is the model's Cramer-Rao bound) or "cog" (an
        attitude fitted to windowed centres of gravity, as flight software computes it).
    """

    n_trials: int = 100
    rate_rad_s: float = 1.0 * DEG
    seed: int = 0
    n_orientations: int = 2000
    n_slew_trials: int = 20
    model: str = "reed"
    n_rate_trials: int | None = None
    slew_full_grid: bool = True
    refine: str = "model"

    def __post_init__(self) -> None:
        if self.refine not in ("model", "cog"):
            raise InputError(f"refine must be 'model' or 'cog', got {self.refine!r}")
