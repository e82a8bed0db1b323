"""How a datasheet is computed: its counts, rate, seed and model, checked on construction."""

from __future__ import annotations

from dataclasses import dataclass

from starsense._validate import check_count
from starsense.analysis.availability.pointings import MAX_ORIENTATIONS, ORIENTATION_COST
from starsense.analysis.datasheet.sections import SheetSettings
from starsense.analysis.inputs import FRAME_COST, MAX_FRAMES
from starsense.analysis.slew import MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST
from starsense.errors import InputError
from starsense.units import DEG, RAD_TO_DEG

__all__ = ["DatasheetSettings", "sheet_settings"]


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
        """Check the counts against their caps before any work (one-line InputError)."""
        if self.refine not in ("model", "cog"):
            raise InputError(f"refine must be 'model' or 'cog', got {self.refine!r}")
        counts = {
            "n_trials": check_count(self.n_trials, "n_trials", MAX_FRAMES, FRAME_COST, 0),
            "n_orientations": check_count(
                self.n_orientations, "n_orientations", MAX_ORIENTATIONS, ORIENTATION_COST
            ),
            "n_slew_trials": check_count(
                self.n_slew_trials, "n_slew_trials", MAX_TRIALS_PER_POINT, SLEW_TRIAL_COST
            ),
        }
        if self.n_rate_trials is not None:
            counts["n_rate_trials"] = check_count(
                self.n_rate_trials, "n_rate_trials", MAX_FRAMES, FRAME_COST, 0
            )
        for name, value in counts.items():
            object.__setattr__(self, name, value)


def sheet_settings(
    settings: DatasheetSettings, catalog_name: str, cut: float | None
) -> SheetSettings:
    """Return the settings as a datasheet records them (its ``settings`` section)."""
    return SheetSettings(
        catalog=catalog_name,
        model=settings.model,
        n_trials=settings.n_trials,
        rate_deg_s=settings.rate_rad_s * RAD_TO_DEG,
        seed=settings.seed,
        n_orientations=settings.n_orientations,
        n_slew_trials=settings.n_slew_trials,
        catalog_cut_mag=cut,
        fov="rectangular (the detector)",
    )
