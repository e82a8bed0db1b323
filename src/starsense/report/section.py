"""What a report section is, and what it is given to build itself.

A section builder is a function ``builder(ctx: ReportContext) -> Section``. It computes its
numbers from ``ctx``, saves its figures with :meth:`ReportContext.save_figure` and returns an HTML
fragment, a few rows for the summary box and its numbers for ``report.json``. The builders the
report runs, in order, are listed in :data:`starsense.report.build.SECTION_BUILDERS`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from matplotlib.figure import Figure

from starsense.analysis.sensor_detection import SensorDetection, sensor_detection
from starsense.catalog import Catalog
from starsense.photometry.stars import BlackBodyStars
from starsense.report.sensors import SensorSpec
from starsense.sensor import Sensor


@dataclass(frozen=True)
class Section:
    """One section of the report.

    Attributes
    ----------
    key : str
        Anchor id in index.html and key of the section's numbers in report.json.
    title : str
    html : str
        The section body (HTML fragment, without the title).
    figures : tuple of str
        PNG files the section wrote, relative to the report directory.
    summary : tuple of (str, str)
        (label, value) rows for the summary box at the top of the page, both HTML.
    data : dict
        JSON-serialisable numbers of the section.
    """

    key: str
    title: str
    html: str
    figures: tuple[str, ...] = ()
    summary: tuple[tuple[str, str], ...] = ()
    data: dict = field(default_factory=dict)


@dataclass
class ReportContext:
    """Everything a section builder needs.

    Attributes
    ----------
    work_dir : Path
        Where figures go (a temporary directory renamed to the report directory at the end).
    catalog_name : str
    n_catalog : int
        Rows of the catalogue (stars used + skipped by the black-body fit).
    stars : dict of str -> BlackBodyStars
        One black-body fit of the catalogue per colour system it has; the first is the primary
        one, used wherever a single star set is needed.
    diameter_m, exposure_s : float
        The user's sensor: aperture D (m) and exposure t (s).
    sensors : tuple of SensorSpec
        Real sensors to compare with the limit (may be empty).
    seed : int
        Root seed of the stochastic parts (low-photon Monte Carlo).
    low_photon_trials : int
    progress : callable(str)
    sensor : starsense.sensor.Sensor or None
        The sensor of the slew (and later availability) sections.
    slew_trials : int
        Monte Carlo trials per (magnitude, rate) of the slew section.
    slew_results : dict of str -> SlewResult
        The slew section's results by sensitivity model, reused by later sections.
    catalog : Catalog or None
        The catalogue the report was built from, as loaded (any ``--catalog`` spec); None when
        the report was given black-body stars alone. Sections that render frames need it.
    detection_cache : SensorDetection or None
        The sensor's detection (limit, slew run on its own grid, m_t(w)) once computed: see
        :meth:`detection`.
    mass_kg, power_w : float or None
        The unit's mass and power for the performance summary (given by the user, or None).
    """

    work_dir: Path
    catalog_name: str
    n_catalog: int
    stars: dict[str, BlackBodyStars]
    diameter_m: float
    exposure_s: float
    sensors: tuple[SensorSpec, ...] = ()
    seed: int = 0
    low_photon_trials: int = 100
    progress: Callable[[str], None] = lambda message: None
    sensor: Sensor | None = None
    slew_trials: int = 20
    datasheet_trials: int = 40
    slew_results: dict = field(default_factory=dict)
    catalog: Catalog | None = None
    detection_cache: SensorDetection | None = None
    mass_kg: float | None = None
    power_w: float | None = None

    @property
    def primary(self) -> BlackBodyStars:
        """The primary star set: the first black-body fit."""
        return next(iter(self.stars.values()))

    def detection(self) -> SensorDetection:
        """Return the sensor's detection (Reed model, the report's trials and seed), computed once.

        The run its datasheet makes (:func:`starsense.analysis.sensor_detection.sensor_detection`),
        so every section uses the sensor's own limit, slew grid and threshold curve.
        """
        if self.detection_cache is None:
            self.detection_cache = sensor_detection(
                self.sensor, model="reed", n_trials=self.slew_trials, rng=self.seed
            )
            if self.detection_cache.slew is not None:
                self.slew_results.setdefault("reed", self.detection_cache.slew)
        return self.detection_cache

    def save_figure(self, fig: Figure, name: str, dpi: int = 110) -> str:
        """Write ``fig`` as ``work_dir/name`` (PNG) and return ``name``."""
        fig.savefig(self.work_dir / name, dpi=dpi, format="png")
        return name
