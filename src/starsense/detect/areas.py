"""Detection per attitude-determination area (Lin et al. 2024).

Stars found on an area frame, each tagged with the area its centroid falls in.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from starsense.detect.threshold import detect_stars

if TYPE_CHECKING:
    from starsense.render.areas import AreaFrame

__all__ = ["detect_in_areas"]


def detect_in_areas(area_frame: AreaFrame, **kwargs):
    """Detect stars in an :class:`AreaFrame` with its sensor's logic.

    Returns
    -------
    detections : Detections
    area : ndarray of int, shape (N,)
        Area number of each detection's centroid.
    """
    image = area_frame.frame.image
    det = detect_stars(image, area_frame.sensor.detection, **kwargs)
    pa = area_frame.pixel_area
    xi = np.clip(np.round(det.x).astype(int), 0, pa.shape[1] - 1)
    yi = np.clip(np.round(det.y).astype(int), 0, pa.shape[0] - 1)
    return det, pa[yi, xi].astype(int)
