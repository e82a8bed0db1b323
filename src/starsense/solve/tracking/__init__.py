"""Tracking: a prior attitude predicts the stars, windows around them are searched, matched.

:func:`~starsense.solve.tracking.track.track_frame` tracks one frame with a
:class:`~starsense.solve.solver.Solver` (its detector and identifier);
:class:`~starsense.solve.tracking.tracker.Tracker` runs a sequence and measures the body rate.
"""

from starsense.solve.tracking.track import Prior, TrackMode, TrackSolution, track_frame
from starsense.solve.tracking.tracker import Tracker

__all__ = ["Prior", "TrackMode", "TrackSolution", "Tracker", "track_frame"]
