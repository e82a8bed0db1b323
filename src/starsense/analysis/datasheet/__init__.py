"""The datasheet: what a given sensor will do, predicted and verified in the same run.

See :func:`datasheet` (and :func:`build_datasheet`, the same from a settings object) and
:func:`compare`; the result is the typed :class:`Datasheet` (:mod:`.sections`). The parts are
the centroid noise model (:mod:`.noise`), the per-attitude Fisher propagation (:mod:`.field`),
the other error terms (:mod:`.terms`, :mod:`.budget`), the predictions (:mod:`.predict`) and
the Monte Carlo check (:mod:`.verify`).
"""

from starsense.analysis.datasheet.compare import Comparison, ComparisonRow, compare
from starsense.analysis.datasheet.sections import Datasheet
from starsense.analysis.datasheet.sheet import SCHEMA, DatasheetSettings, build_datasheet, datasheet

__all__ = [
    "SCHEMA",
    "Comparison",
    "ComparisonRow",
    "Datasheet",
    "DatasheetSettings",
    "build_datasheet",
    "compare",
    "datasheet",
]
