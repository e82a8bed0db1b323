"""The datasheet: what a given sensor will do, predicted and verified in the same run.

See :func:`build_datasheet`; the parts are the centroid noise model (:mod:`.noise`), the
per-attitude Fisher propagation (:mod:`.field`), the other error terms (:mod:`.terms`), the
predictions (:mod:`.predict`) and the Monte Carlo check (:mod:`.verify`).
"""

from starsense.analysis.datasheet.sheet import SCHEMA, Datasheet, DatasheetSettings, build_datasheet

__all__ = ["SCHEMA", "Datasheet", "DatasheetSettings", "build_datasheet"]
