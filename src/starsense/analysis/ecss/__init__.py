"""The ECSS-E-ST-60-20C performance statement of a sensor (error classes per axis and rate).

- :mod:`~starsense.analysis.ecss.confidence`: confidence levels and their Gaussian factors;
- :mod:`~starsense.analysis.ecss.axes`: per-axis (X, Y, Z) attitude errors;
- :mod:`~starsense.analysis.ecss.classes`: the ECSS classes, bias or noise at a rate;
- :mod:`~starsense.analysis.ecss.sky`: the datasheet's sky, per attitude;
- :mod:`~starsense.analysis.ecss.terms`: each error term's values;
- :mod:`~starsense.analysis.ecss.statement`: the statement;
- :mod:`~starsense.analysis.ecss.export`: its CSV (a pointing budget's table) and text.
"""

from starsense.analysis.ecss.confidence import gaussian_factor, mixture_bound, parse_confidence
from starsense.analysis.ecss.statement import SCHEMA, Statement, ecss_statement

__all__ = [
    "SCHEMA",
    "Statement",
    "ecss_statement",
    "gaussian_factor",
    "mixture_bound",
    "parse_confidence",
]
