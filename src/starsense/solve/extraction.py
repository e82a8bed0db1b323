"""The Solver's star extraction: the robust detector, and the quick one tried first.

A real frame is solved first from a quick extraction (:mod:`starsense.detect.quick`: a coarse
background, a plain threshold, about two passes over the frame): most frames have enough bright
stars for it. When those stars do not solve (too few, a background the coarse mesh misjudges,
clutter), the frame is solved again from the robust extraction (background map by clipped
medians and MADs, hot pixels removed, the PSF's matched filter, shape tests), whose result is
returned. A failed quick attempt costs about a millisecond at a known field; with an unknown
field it costs a pinhole scale search (no distortion guess, no mirror image), and the robust
attempt then has a work budget of its own (``max_patterns`` of
:class:`~starsense.solve.identifiers.FieldIdentifiers`), so that a quick attempt on clutter
does not spend the budget the robust one needs. A frame whose noise is clipped at a floor is
declined by the quick extraction before any identification (:mod:`starsense.detect.quick`).

Which extraction a solution came from is in its ``stage_ms``: ``quick_ms`` (the time of a
quick attempt that did not solve) appears only when the robust extraction followed it.
"""

from __future__ import annotations

from typing import Literal

from starsense.detect import StarDetector

#: which extraction a Solver runs: "auto" (quick first, then robust), "quick" or "robust" alone
Extraction = Literal["auto", "quick", "robust"]
EXTRACTIONS = ("auto", "quick", "robust")
#: PSF sigma of the matched filter when no sensor is given, px (a focused star tracker:
#: 0.7-1.5 px; the filter's gain is within 10 % of optimal for 0.6-1.6 px)
DEFAULT_PSF_SIGMA_PX = 1.0


def robust_detector(sensor, logic, settings) -> StarDetector:
    """Return the Solver's robust full-frame detector.

    With ``background="known"`` the sensor's own (:meth:`StarDetector.for_sensor`); else a
    background map, a matched filter of the sensor's PSF (1 px without a sensor) and the
    ``threshold_sigma`` threshold.

    Parameters
    ----------
    sensor : Sensor or None
    logic : DetectionThresholds
        The detection floors.
    settings : SolverSettings

    Returns
    -------
    StarDetector
    """
    if settings.background == "known":
        return StarDetector.for_sensor(sensor)
    return _detector(sensor, logic, settings, background="auto", matched_filter=True)


def quick_detector(sensor, logic, settings) -> StarDetector | None:
    """Return the quick detector tried before the robust one, or None when it is not tried.

    Tried with ``extraction="quick"`` or "auto" on real frames (``background="auto"``).

    Parameters
    ----------
    sensor : Sensor or None
    logic : DetectionThresholds
    settings : SolverSettings

    Returns
    -------
    StarDetector or None
    """
    if settings.extraction == "robust" or settings.background == "known":
        return None
    return _detector(sensor, logic, settings, background="quick")


def _detector(sensor, logic, settings, **options) -> StarDetector:
    """Return a CoG detector at the settings' threshold and SNR, with the sensor's PSF."""
    return StarDetector(
        logic,
        "cog",
        threshold_sigma=settings.threshold_sigma,
        min_snr=settings.threshold_sigma,
        psf_sigma_px=sensor.detector.psf_sigma_px if sensor is not None else DEFAULT_PSF_SIGMA_PX,
        **options,
    )


def solution_detector(solver, solution) -> StarDetector:
    """Return the detector whose detections a frame's solution indexes (its ``matches``).

    Parameters
    ----------
    solver : Solver
        The solver that solved the frame.
    solution : Solution
        Its solution of the frame.

    Returns
    -------
    StarDetector
        The quick detector, unless it was not tried or the robust one followed it; the
        spike-keeping one when the robust one held spikes aside and did not solve.
    """
    if "robust_ms" in solution.stage_ms:  # solved with its spikes (starsense.solve.sharp)
        return solver.spike_detector
    quick = solver.quick_detector
    return solver.detector if quick is None or "quick_ms" in solution.stage_ms else quick
