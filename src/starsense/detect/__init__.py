"""Detection and centroiding of stars in a frame.

Pixel convention (shared with :mod:`starsense.render` and :mod:`starsense.sensor`): images are
arrays (rows, columns); pixel centres are at integer coordinates, pixel (row r, column c) covering
x in [c - 0.5, c + 0.5) and y in [r - 0.5, r + 0.5); centroids are (x, y) = (column, row).
"""

from starsense.detect.background import Background, constant_background, estimate_background
from starsense.detect.detections import Detections
from starsense.detect.hot_pixels import hot_pixel_mask
from starsense.detect.stack import detect_stack
from starsense.detect.threshold import DetectionLogic, StarDetector, detect_stars

__all__ = [
    "Background",
    "DetectionLogic",
    "Detections",
    "StarDetector",
    "constant_background",
    "detect_stack",
    "detect_stars",
    "estimate_background",
    "hot_pixel_mask",
]
