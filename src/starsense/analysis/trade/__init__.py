"""Trade studies: the datasheet's predictions over a grid of designs, fast.

:func:`predict` (the datasheet without frames), the grid of designs around a base sensor TOML
(:mod:`.grid`: ``KEY=SPEC``, coupled keys), and :func:`run_trade` (rows, Pareto sets, the
check on rendered frames). ``starsense trade`` and the design page are thin layers over these.
"""

from starsense.analysis.trade.grid import (
    KEEP,
    MAX_DESIGNS_IN_PROCESS,
    MAX_DESIGNS_ON_CLUSTER,
    Design,
    base_document,
    designs,
    grid_size,
    parse_vary,
)
from starsense.analysis.trade.predict import predict, prediction_settings
from starsense.analysis.trade.study import PARETO, TradeRow, TradeStudy, pareto_mask, run_trade

__all__ = [
    "KEEP",
    "MAX_DESIGNS_IN_PROCESS",
    "MAX_DESIGNS_ON_CLUSTER",
    "PARETO",
    "Design",
    "TradeRow",
    "TradeStudy",
    "base_document",
    "designs",
    "grid_size",
    "pareto_mask",
    "parse_vary",
    "predict",
    "prediction_settings",
    "run_trade",
]
