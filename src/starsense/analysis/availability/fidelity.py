"""Full-fidelity check: availability from rendered frames against the threshold model.

Frames are rendered at random attitudes while the sensor slews, passed through the sensor's
detector, and the stars detected are compared with the stars the threshold model counts at the
same attitudes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense._validate import check_count, check_int
from starsense.analysis.availability.checks import check_rates
from starsense.analysis.availability.field import FieldStars, catalog_stars
from starsense.analysis.availability.results import N_MIN_LOST_IN_SPACE, percent
from starsense.analysis.availability.threshold import ThresholdCurve
from starsense.analysis.inputs import FRAME_COST, MAX_FRAMES, root_seed
from starsense.detect import StarDetector
from starsense.render.scene import render_frame
from starsense.units import DEG, to_edge

__all__ = ["FidelityCheck", "fidelity_check"]


@dataclass(frozen=True)
class FidelityCheck:
    """Availability from rendered frames against the threshold model, at the same attitudes.

    Attributes
    ----------
    rate_rad_s : float
        Cross-axis slew rate of the frames, rad/s (about camera y: streaks along the rows).
    threshold_mag : float
        m_t of the threshold model at that rate (capped at the catalogue cut).
    n_min : int
        Stars needed.
    model_counts, frame_counts : ndarray, shape (S,)
        Stars the threshold model counts in the detector field; catalogue stars (within the
        cut) detected in the rendered frame (a detection matched to a true star image).
    n_spurious : ndarray, shape (S,)
        Detections not matched to any catalogue star of the cut (fainter stars, noise).
    model_available, frame_available : ndarray of bool, shape (S,)
        Whether each attitude is available by the model, by the frames.
    model_name : str
        Sensitivity model of the rendering.
    """

    rate_rad_s: float
    threshold_mag: float
    n_min: int
    model_counts: NDArray[np.intp]
    frame_counts: NDArray[np.intp]
    n_spurious: NDArray[np.intp]
    model_available: NDArray[np.bool_]
    frame_available: NDArray[np.bool_]
    model_name: str = ""

    @property
    def rate_deg_s(self) -> float:
        """Slew rate, deg/s (for output)."""
        return float(to_edge(self.rate_rad_s, DEG))

    @property
    def n_frames(self) -> int:
        """Frames rendered."""
        return len(self.frame_counts)

    @property
    def model_availability(self) -> float:
        """Fraction of the attitudes the threshold model calls available."""
        return float(self.model_available.mean())

    @property
    def frame_availability(self) -> float:
        """Fraction of the frames with at least `n_min` stars detected."""
        return float(self.frame_available.mean())

    @property
    def optimistic(self) -> int:
        """Frames the threshold model calls available that the detector does not solve."""
        return int((self.model_available & ~self.frame_available).sum())

    @property
    def pessimistic(self) -> int:
        """Frames the detector solves that the threshold model calls unavailable."""
        return int((~self.model_available & self.frame_available).sum())

    def to_dict(self) -> dict:
        """Return the numbers as JSON-ready values (rate in deg/s)."""
        return {
            "rate_deg_s": self.rate_deg_s,
            "threshold_mag": self.threshold_mag,
            "n_min": self.n_min,
            "n_frames": self.n_frames,
            "model_availability": self.model_availability,
            "frame_availability": self.frame_availability,
            "optimistic_frames": self.optimistic,
            "pessimistic_frames": self.pessimistic,
            "mean_model_count": float(self.model_counts.mean()),
            "mean_frame_count": float(self.frame_counts.mean()),
            "mean_spurious": float(self.n_spurious.mean()),
            "model": self.model_name,
        }

    def lines(self) -> list[str]:
        """Return a human-readable summary."""
        return [
            f"full-fidelity check at {self.rate_deg_s:g} deg/s, N_min = {self.n_min}, "
            f"{self.n_frames} rendered frames ({self.model_name} model)",
            f"  threshold model (m_t = {self.threshold_mag:.2f}): "
            f"{percent(self.model_availability)} available, "
            f"{self.model_counts.mean():.2f} stars per field",
            f"  rendered + detected: {percent(self.frame_availability)} available, "
            f"{self.frame_counts.mean():.2f} stars detected per frame "
            f"(+{self.n_spurious.mean():.2f} unmatched)",
            f"  model optimistic in {self.optimistic} frames, pessimistic in {self.pessimistic}",
        ]


def _detect(frame: Any, sensor: Any) -> NDArray[np.float64]:
    """Return centroids (K, 2), (x, y) pixels, of the stars the sensor's detector finds.

    :class:`starsense.detect.StarDetector` with the sensor's logic, bias as background.
    """
    found = StarDetector.for_sensor(sensor)(frame.image)
    return np.stack([np.asarray(found.x, float), np.asarray(found.y, float)], axis=-1)


def _truth_xy_mag(frame: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return mid-exposure positions (K, 2) and magnitudes (K,) of a rendered frame's stars."""
    stars = frame.truth.stars
    xy = np.stack([np.asarray(stars.x_mid, float), np.asarray(stars.y_mid, float)], axis=-1)
    return xy.reshape(-1, 2), np.asarray(stars.mag, dtype=np.float64).reshape(-1)


def _match(
    centroids: NDArray[np.float64], truth_xy: NDArray[np.float64], radius: float
) -> tuple[int, int]:
    """Return (true stars matched by a detection, detections matching no true star)."""
    matched_truth = np.zeros(len(truth_xy), dtype=bool)
    if not (len(centroids) and len(truth_xy)):
        return 0, len(centroids)
    dist, idx = cKDTree(truth_xy).query(centroids, distance_upper_bound=radius)
    ok = np.isfinite(dist)
    matched_truth[idx[ok]] = True
    return int(matched_truth.sum()), int((~ok).sum())


def fidelity_check(
    sensor: Any,
    catalog: Any,
    curve: ThresholdCurve,
    *,
    rate_rad_s: float,
    n_trials: int = 50,
    n_min: int = N_MIN_LOST_IN_SPACE,
    max_mag: float = 5.75,
    model: str = "reed",
    band: str = "V",
    rng: int | np.random.Generator | None = 0,
    match_radius_px: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> FidelityCheck:
    """Render frames at random attitudes, detect, and compare with the threshold model.

    Each frame is rendered (:func:`starsense.render.scene.render_frame`) from the catalogue
    stars with ``mag <= max_mag`` (the on-board catalogue) while the sensor slews about its
    camera y axis at `rate_rad_s` (streaks along the rows, as in the slew simulation), then
    passed through the detector. A detection counts when its centroid lies within
    `match_radius_px` of a true star's mid-exposure position (default: half the streak length
    plus 3 PSF sigma). The threshold model counts the stars ``<= min(m_t(w), max_mag)`` in the
    rectangular detector field at the same attitude.

    Parameters
    ----------
    sensor : starsense.sensor.Sensor
        The star tracker.
    catalog : Catalog
        The stars to render.
    curve : ThresholdCurve
        The threshold model.
    rate_rad_s : float
        Cross-axis slew rate, rad/s.
    n_trials : int
        Frames to render.
    n_min : int
        Stars needed.
    max_mag : float
        Catalogue cut.
    model : str
        Sensitivity model of the rendering.
    band : str
        Magnitude band.
    rng : None, int or numpy.random.Generator
        Root seed of the attitudes and the frames' noise (a Generator gives one seed drawn
        from it).
    match_radius_px : float, optional
        Radius of a match, px.
    progress : callable(done, total), optional
        Called after each frame.

    Returns
    -------
    FidelityCheck

    Raises
    ------
    InputError
        On bad counts or rates.
    """
    n_frames = check_count(n_trials, "n_trials", MAX_FRAMES, FRAME_COST)
    n_min = check_int(n_min, "n_min", 1)
    w = float(check_rates(rate_rad_s, "rate_rad_s")[0])
    vectors, mags = catalog_stars(catalog, max_mag, band=band)
    m_t = float(min(curve([w])[0], max_mag))
    seed = root_seed(rng)
    rng = np.random.default_rng(seed)
    attitudes = Rotation.random(n_frames, rng=rng)
    model_counts = FieldStars.build(sensor.fov(), attitudes, vectors, mags).counts(m_t)
    streak = sensor.streak_length_px(w)
    radius = (
        float(match_radius_px)
        if match_radius_px is not None
        else 0.5 * streak + 3.0 * sensor.detector.psf_sigma_px + 1.0
    )
    children = np.random.SeedSequence(seed).spawn(n_frames)
    frame_counts = np.zeros(n_frames, dtype=np.intp)
    spurious = np.zeros(n_frames, dtype=np.intp)
    for i in range(n_frames):
        frame = render_frame(
            sensor,
            attitudes[i],
            catalog,
            rate_rad_s=np.array([0.0, w, 0.0]),
            model=model,
            band=band,
            max_mag=max_mag,
            rng=np.random.default_rng(children[i]),
            keep_expected=False,
        )
        truth_xy, truth_mag = _truth_xy_mag(frame)
        frame_counts[i], spurious[i] = _match(
            _detect(frame, sensor), truth_xy[truth_mag <= max_mag], radius
        )
        if progress is not None:
            progress(i + 1, n_frames)
    return FidelityCheck(
        rate_rad_s=w,
        threshold_mag=m_t,
        n_min=n_min,
        model_counts=model_counts,
        frame_counts=frame_counts,
        n_spurious=spurious,
        model_available=model_counts >= n_min,
        frame_available=frame_counts >= n_min,
        model_name=model,
    )
