"""What each part of the limit section hands back: its HTML, its numbers and its figures."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Part"]


@dataclass
class Part:
    """One part of a report section.

    Attributes
    ----------
    html : list of str
        HTML blocks, in page order.
    data : dict
        Numbers for report.json, merged into the section's data in part order.
    figures : list of str
        File names of the figures written.
    """

    html: list[str] = field(default_factory=list)
    data: dict = field(default_factory=dict)
    figures: list[str] = field(default_factory=list)
