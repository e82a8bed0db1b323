"""Figures, one module per analysis: functions take ``ax=`` and return the figure.

The modules import matplotlib (~0.3 s) at their top. A command that draws a figure only when
asked (``--plot``) reaches them as attributes of this package (``plotting.limits``), which
imports the module on first use, so a run without a figure does not load matplotlib.
``from starsense.plotting.limits import ...`` works as usual.
"""

import importlib
from types import ModuleType

#: the figure modules, imported on first use as attributes of the package
MODULES = (
    "availability",
    "datasheet",
    "explain",
    "figure",
    "guide_stars",
    "limits",
    "mission",
    "slew",
    "slew_study",
)

__all__ = ["MODULES"]


def __getattr__(name: str) -> ModuleType:
    """Import the figure module ``name`` (one of :data:`MODULES`) on first use."""
    if name in MODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
