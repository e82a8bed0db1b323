"""What the detector returns: :class:`Detections`, the stars found in a frame, brightest first."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Detections"]


@dataclass(frozen=True)
class Detections:
    """Detected stars, brightest first (columnar).

    Attributes
    ----------
    x, y : array (N,)
        Centroids, pixels (x = column, y = row; pixel centres at integers).
    integrated_counts : array (N,)
        Background-subtracted counts summed over the star's lit pixels.
    n_pixels : array (N,) int
        Lit pixels.
    peak_counts : array (N,)
        Largest raw count in the star.
    saturated : array (N,) bool
        Some pixel at the saturation level.
    bbox : array (N, 4) int
        row0, row1, col0, col1 (half-open) of the lit pixels.
    fit_ok : array (N,) bool
        The centroid method succeeded (always True for cog/iwcog).
    n_candidates : int
        Contiguous lit regions before the size and intensity cuts.
    noise_counts : float
        Background noise used for the thresholds.
    time_ms : float
    counts : dict
        What each cut did: ``pixels_above_threshold``, ``hot_pixels`` (removed before
        labelling), ``candidates`` (lit regions), ``rejected_size`` (too few or too many
        pixels), ``rejected_faint`` (integrated counts, significance or peak too low),
        ``rejected_shape`` (not point-like: plateaus, streaks), ``saturated`` (detections
        with a pixel at saturation, kept), ``detections``.
    """

    x: np.ndarray
    y: np.ndarray
    integrated_counts: np.ndarray
    n_pixels: np.ndarray
    peak_counts: np.ndarray
    saturated: np.ndarray
    bbox: np.ndarray
    fit_ok: np.ndarray
    n_candidates: int = 0
    noise_counts: float = 0.0
    time_ms: float = 0.0
    method: str = "cog"
    extra: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.x)

    def to_dict(self) -> dict:
        """Return the detections as a JSON-able dictionary (no bounding boxes or fit flags)."""
        return {
            "x": self.x.tolist(),
            "y": self.y.tolist(),
            "integrated_counts": self.integrated_counts.tolist(),
            "n_pixels": self.n_pixels.tolist(),
            "peak_counts": self.peak_counts.tolist(),
            "saturated": self.saturated.tolist(),
            "n_candidates": self.n_candidates,
            "time_ms": self.time_ms,
        }
