"""The HTML performance report: figures, tables and the numbers behind them.

``build_report(out_dir)`` writes ``out_dir/index.html``, its PNG figures and ``report.json``.
The page is a list of sections (:data:`starsense.report.build.SECTION_BUILDERS`), each a function
of a :class:`ReportContext` returning a :class:`Section`; the first is the physical limit of
Fialho & Mortari 2019.
"""

from starsense.report.build import (
    DEFAULT_DIAMETER_M,
    DEFAULT_EXPOSURE_S,
    SECTION_BUILDERS,
    build_report,
)
from starsense.report.limits import fov_table, limit_section, table1_rows
from starsense.report.section import ReportContext, Section
from starsense.report.sensors import SensorSpec, load_sensor_table, theta_from_sigmas

__all__ = [
    "DEFAULT_DIAMETER_M",
    "DEFAULT_EXPOSURE_S",
    "SECTION_BUILDERS",
    "ReportContext",
    "Section",
    "SensorSpec",
    "build_report",
    "fov_table",
    "limit_section",
    "load_sensor_table",
    "table1_rows",
    "theta_from_sigmas",
]
