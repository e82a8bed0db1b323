"""The star-tracker pipeline: a frame in, an attitude out.

image -> background -> detection -> centroids -> unit vectors -> identification -> attitude

The optics are known three ways, from best to least: a sensor (preset or TOML), whose pinhole +
distortion model unprojects the centroids; a horizontal field of view (``fov_rad``), a pinhole
with the principal point at the centre, taken as an estimate when the frame does not solve at
that field; nothing: the centroids are unprojected with a nominal field and the FOV-free
pattern hashing (edge ratios are scale-invariant) finds the scale over 5-30, 25-70, then
2.8-6 deg (Gaia; :func:`starsense.identify.fields.unknown_field_plan`).

The attitude is fitted to all matched stars (Wahba's problem by SVD, :mod:`starsense.attitude`,
with its covariance, Fialho & Mortari eq. 21), against their apparent places when the frame's
time is known (:mod:`starsense.catalog.apparent`): the true ICRS attitude.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Literal

import numpy as np

from starsense.catalog.table import Catalog
from starsense.detect import StarDetector
from starsense.identify.fields import FieldRange, known_field_catalog
from starsense.sensor import DetectionThresholds, Sensor, load_sensor
from starsense.solve.attitude_step import solution_of
from starsense.solve.centroid_path import solve_centroid_list
from starsense.solve.centroids import CentroidPoints, check_frame_shape
from starsense.solve.counts import (
    detection_counts,
    identification_counts,
    max_candidates,
    ms,
)
from starsense.solve.extraction import Extraction, quick_detector, robust_detector
from starsense.solve.frames import solve_frame_file
from starsense.solve.identifiers import FieldIdentifiers
from starsense.solve.near_miss import FrameEvidence
from starsense.solve.parity import unsolved
from starsense.solve.pinhole import pinhole_vectors
from starsense.solve.settings import Algorithm, BackgroundMode, SolverSettings, solver_settings
from starsense.solve.sharp import retry_with_spikes, spike_detector
from starsense.solve.solution import Solution
from starsense.solve.streak_pieces import joined_pieces
from starsense.solve.streaks import matched_measurements
from starsense.units import DEG

__all__ = [
    "NOMINAL_FOV_RAD",
    "UNKNOWN_FOV_RANGE_RAD",
    "Solution",
    "Solver",
    "SolverSettings",
    "max_candidates",
    "pinhole_vectors",
]

#: field range searched when the optics are unknown, rad (5-30, 25-70, then 2.8-6 deg)
UNKNOWN_FOV_RANGE_RAD = (2.8 * DEG, 70.0 * DEG)
#: the field the centroids are unprojected with before the scale is found, rad (15 deg)
NOMINAL_FOV_RAD = 15.0 * DEG


class Solver:
    """Configure once (database, detector), then call on frames: ``Solver(...)(image)``.

    Parameters
    ----------
    sensor : str, Path or Sensor, optional
        Sensor preset, TOML path or object: known optics and its detection floors.
    fov_rad : float, optional
        Horizontal field across the image width (pinhole), rad, in [0.5, 120] deg, when no
        sensor is given.
    catalog : Catalog or str
        The catalogue of the database: an object (used for every field range, e.g. one
        filtered in Python), or a spec (:func:`starsense.catalog.load_catalog`; default the
        bundled Hipparcos, with the narrow range of an unknown field searched in the bundled
        Gaia when installed). Loaded once, when first needed.
    algorithm : {"hashing", "triangle"}
        Lost-in-space algorithm (triangle needs a known field).
    threshold_sigma : float
        Lit-pixel threshold above the background map, in noise sigmas.
    centroid_sigma_px : float or "snr", optional
        Centroid noise assumed for the centroid fit's weights and covariance, pixels; "snr"
        (needs a sensor) uses each star's own noise (:func:`starsense.detect.centroid.
        cog_sigma_px`: photon noise plus read noise over its centroid window). Default 0.3 px
        (a real frame's centroids carry systematic errors beyond their photons': the lens's
        distortion left, its PSF): with a sensor the attitude's sigmas are then the model
        fit's (``refine``), and the centroids' weights only start it.
    background : {"auto", "known"}
        "auto" estimates a background map and noise (real frames); "known" (needs a sensor)
        subtracts the sensor's bias and applies its detection logic as is (simulated frames).
    extraction : {"auto", "quick", "robust"}
        With ``background="auto"``: "auto" solves a frame first from a quick extraction, then,
        if that does not solve, from the robust one; "quick" or "robust"
        alone (:mod:`starsense.solve.extraction`).
    apparent : bool
        Fit the attitude to the stars' apparent places when the frame's time is known (default).
    observer_velocity_m_s : array_like, shape (3,), optional
        The observer's velocity relative to the geocentre (orbit), ICRS axes, m/s.
    refine : {"model", "cog"}, optional
        The attitude's last step. "model" (the default with a sensor) fits the sensor's
        forward model to the identified stars' pixels by maximum likelihood, neighbours and
        rate included, and reports the inverse Fisher information as the solution's
        covariance (:mod:`starsense.solve.refine`); "cog" (the default without one) keeps the
        attitude fitted to the centroids.
    sky : Catalog or str, optional
        The catalogue whose stars the model fit draws as neighbours of the identified ones
        (default: ``catalog``): give the deepest catalogue of the sky the frames show (frames
        rendered from another catalogue, a real sky fainter than the database).
    max_patterns : int or None
        Work budget of one solve, 4-star patterns over all its identification attempts, then
        status "timeout" (:data:`~starsense.solve.settings.MAX_PATTERNS`; None: no bound).

    Attributes
    ----------
    sensor : Sensor or None
        The sensor.
    settings : SolverSettings
        Everything else it was configured with.
    logic : DetectionThresholds
        The detection logic (the sensor's, else a permissive one).
    """

    def __init__(
        self,
        sensor=None,
        *,
        fov_rad: float | None = None,
        catalog: Catalog | str = "hipparcos",
        algorithm: Algorithm = "hashing",
        threshold_sigma: float = 5.0,
        centroid_sigma_px: float | Literal["snr"] | None = None,
        background: BackgroundMode = "auto",
        extraction: Extraction = "auto",
        apparent: bool = True,
        observer_velocity_m_s=None,
        refine: Literal["model", "cog"] | None = None,
        sky: Catalog | str | None = None,
        max_patterns: int | None = SolverSettings.max_patterns,  # settings.MAX_PATTERNS
    ) -> None:
        self.settings: SolverSettings = solver_settings(
            sensor,
            catalog=catalog,
            algorithm=algorithm,
            threshold_sigma=threshold_sigma,
            centroid_sigma_px=centroid_sigma_px,
            background=background,
            extraction=extraction,
            apparent=apparent,
            observer_velocity_m_s=observer_velocity_m_s,
            fov_rad=fov_rad,
            refine=refine,
            sky=sky,
            max_patterns=max_patterns,
        )
        self.sensor = (
            sensor if (sensor is None or isinstance(sensor, Sensor)) else load_sensor(sensor)
        )
        self.logic = (
            self.sensor.detection
            if self.sensor is not None
            else DetectionThresholds(lit_pixel_counts=1e-6, min_pixels=3, min_integrated_counts=0)
        )
        known_fov = 2 * self.sensor.half_fov_rad[0] if self.sensor else self.settings.fov_rad
        catalog = known_field_catalog(catalog, known_fov)  # Gaia for a narrow known field
        budget = self.settings.max_patterns
        self._identifiers = FieldIdentifiers(catalog, algorithm=algorithm, max_patterns=budget)
        self._sky = None if sky is None else FieldIdentifiers(sky, algorithm=algorithm)
        self._detector: StarDetector | None = None
        self._quick: StarDetector | bool | None = False  # not built yet

    @property
    def catalog(self) -> Catalog:
        """The catalogue of the database (a spec is loaded here, once)."""
        return self._identifiers.catalog

    # -- optics -----------------------------------------------------------------------------

    def _unproject(self, x, y, shape, fov_rad=None) -> tuple[np.ndarray, float | None, float]:
        """Return the centroids' unit vectors, the known horizontal FOV and the assumed one.

        The known field is None when it is to be found; the assumed one is the field the
        vectors were computed with. Both in rad. ``fov_rad`` replaces the Solver's field.
        """
        if self.sensor is not None:
            fov = 2.0 * self.sensor.half_fov_rad[0]
            return self.sensor.unproject(x, y), fov, fov
        known = fov_rad if fov_rad is not None else self.settings.fov_rad
        fov = known if known is not None else NOMINAL_FOV_RAD
        return pinhole_vectors(x, y, shape=shape, fov_rad=fov), known, fov

    # -- what tracking needs: the detector and the identifier of a field -------------------

    @property
    def detector(self) -> StarDetector:
        """The robust star detector (:func:`starsense.solve.extraction.robust_detector`)."""
        if self._detector is None:
            self._detector = robust_detector(self.sensor, self.logic, self.settings)
        return self._detector

    @property
    def spike_detector(self) -> StarDetector:
        """The robust detector keeping one- and two-pixel spikes (:mod:`starsense.solve.sharp`)."""
        return spike_detector(self.detector, psf_known=self.sensor is not None)

    @property
    def quick_detector(self) -> StarDetector | None:
        """The quick detector tried first, or None (:mod:`starsense.solve.extraction`)."""
        if self._quick is False:
            self._quick = quick_detector(self.sensor, self.logic, self.settings)
        return self._quick

    def sky_stars(self, band: str):
        """Return the stars the model fit draws in ``band`` (``sky``'s, else the database's)."""
        return (self._sky or self._identifiers).sky(band)

    def field_plan(self) -> list[FieldRange]:
        """Return the field ranges searched, in order, when the field is not known (its plan)."""
        return self._identifiers.plan()

    def identifier(self, fov_rad: float | None = None, field_range: FieldRange | None = None):
        """Return the identifier of a known field or of one range of the unknown-field search.

        Parameters
        ----------
        fov_rad : float, optional
            The known field (full width), rad.
        field_range : FieldRange, optional
            A range of :meth:`field_plan`, when ``fov_rad`` is None (default: its first).

        Returns
        -------
        HashIdentifier or TriangleIdentifier
            Its ``database`` is the identification database.
        """
        return self._identifiers(fov_rad, field_range)

    # -- the pipeline -----------------------------------------------------------------------

    def __call__(self, image, obs_time=None) -> Solution:
        """Solve one frame: detect, identify and estimate the attitude with its covariance.

        Parameters
        ----------
        image : array_like, shape (rows, columns)
            The frame, counts.
        obs_time : str or astropy.time.Time, optional
            When the frame was taken (ISO 8601 UTC): the attitude is then fitted to the stars'
            apparent places (unless the solver was built with ``apparent=False``).

        Returns
        -------
        Solution
            Solved, or the reason why not (no exception for a frame that does not solve).
        """
        t0 = time.perf_counter()
        self._identifiers.start()  # the frame's identifications share one work budget
        a = np.asarray(image)
        check_frame_shape(a.shape, self.sensor)
        stages: dict[str, float] = {}
        quick = self.quick_detector
        if quick is not None:
            alone = self.settings.extraction == "quick"
            sol = self._solve_frame(a, quick, t0, stages, obs_time, first=not alone)
            if sol.solved or alone:
                return sol
            stages = {"quick_ms": ms(t0)}
            if self.sensor is None and self.settings.fov_rad is None:
                self._identifiers.start()  # the quick attempt's scale search had its own budget
        sol = self._solve_frame(a, self.detector, t0, stages, obs_time)
        return retry_with_spikes(  # held-aside spikes
            self, a, sol, t0=t0, stages=stages, obs_time=obs_time, solve=self._solve_frame,
            restart=self._identifiers.start,
        )  # fmt: skip

    def _solve_frame(self, a, detector, t0, stages, obs_time, first=False) -> Solution:
        """Detect and solve frame ``a`` (a ``first`` attempt: at the known field only)."""
        t1 = time.perf_counter()
        det = joined_pieces(self, a, detector(a))  # a long faint streak's pieces: one star
        stages["detect_ms"] = ms(t1)
        counts = detection_counts(a, det)
        if len(det) == 0:
            why = "no star passed the detection logic"
            return Solution("no_stars", why, time_ms=ms(t0), stage_ms=stages, counts=counts)

        def sigma_px(matched, x, vectors):  # streaks re-centroided: starsense.solve.streaks
            return matched_measurements(self, a, det, matched=matched, x=x, vectors=vectors)

        points = CentroidPoints(
            det.x, det.y, det.integrated_counts, a.shape, "detections", det.extra.get("rank")
        )
        sol = self._solve_points(
            points,
            t0,
            stages,
            sigma_px,
            None,
            obs_time,
            parity=not first,
            search=not first,
            image=a,
        )
        return dataclasses.replace(sol, counts={**counts, **sol.counts})

    def solve_centroids(
        self, xy, image_size, *, fov_rad: float | None = None, brightness=None, obs_time=None
    ) -> Solution:
        """Solve a list of centroids measured by any centroider (no image needed).

        Pixel convention (that of :mod:`starsense.detect`): (0, 0) is the centre of the top-left
        pixel, x runs along the columns (to the right) and y along the rows (down); the image
        spans x in [-0.5, width - 0.5), and up to 2 px beyond is an edge star. The optics are
        the Solver's (sensor or ``fov_rad``), or ``fov_rad`` for this call, or unknown (the
        scale is then searched).

        Parameters
        ----------
        xy : array_like, shape (N, 2)
            Centroids (x = column, y = row), pixels.
        image_size : (int, int)
            Width and height of the image, pixels (columns, rows).
        fov_rad : float, optional
            Horizontal field across the image width (pinhole), rad, in [0.5, 120] deg: for
            this call, in place of the Solver's (not with a sensor).
        brightness : array_like, shape (N,), optional
            Anything that grows with brightness (flux, counts); when omitted the centroids are
            taken as listed brightest first.
        obs_time : str or astropy.time.Time, optional
            When the image was taken (ISO 8601 UTC): the attitude is fitted to apparent places.

        Returns
        -------
        Solution
            The same object as an image solve (``centroids_px`` are the given ones, ``matches``
            index them); "too_few_stars" for fewer than 3 centroids.

        Raises
        ------
        InputError
            Centroids not (N, 2) finite numbers, a bad image size or field, brightness not one
            finite value per centroid, an image size that is not the sensor's, a centroid
            more than 2 px outside the image.
        """
        return solve_centroid_list(
            self,
            xy,
            image_size,
            fov_rad=fov_rad,
            brightness=brightness,
            obs_time=obs_time,
            identifiers=self._identifiers,
            whole_way=self._solve_points,
        )

    def _solve_points(self, points, t0, stages, sigma_px, fov_given, obs_time=None, *,
                      parity=True, search=True, image=None):  # fmt: skip
        """Identify centroids (x, y) of an image of ``shape`` and fit the attitude.

        When they do not solve (and are not clutter), their mirror image is tried
        (:func:`starsense.solve.parity.solve_mirrored`, unless ``parity`` is False); without
        a sensor, the scale around the given field (unless ``search`` is False).
        """
        n = len(points.x)
        if n < 3:
            said = f"{n} centroid(s) given" if points.what == "centroids" else f"{n} star(s)"
            why = f"{said}{' detected' * (points.what != 'centroids')}; 3 are needed"
            return Solution("too_few_stars", why, n_detections=n, time_ms=ms(t0), stage_ms=stages)
        vectors, fov_known, fov_assumed = self._unproject(
            points.x, points.y, points.shape, fov_given
        )
        t1 = time.perf_counter()
        self.identifier(fov_known)  # database build or cache load, timed on its own
        stages["database_ms"] = ms(t1)
        t2 = time.perf_counter()
        identifier, ident, fov_known, k1 = self._identifiers.identify(
            vectors,
            points.ranking,
            fov_known_rad=fov_known,
            fov_assumed_rad=fov_assumed,
            estimate=self.sensor is None and search,
            evidence=FrameEvidence.of(image, points, self.sky_stars),
        )
        stages["identify_ms"] = ms(t2)
        if not ident.solved:
            again = (t0, stages, sigma_px, fov_given, obs_time)

            def flipped(mx, my, f):  # the mirror image, solved the same way (not flipped again)
                mirror = CentroidPoints(mx, my, f, points.shape, points.what, points.rank)
                return self._solve_points(mirror, *again, parity=False)

            sol = unsolved(points, ident, mirrored=flipped if parity else None, stages=stages,
                           time_ms=ms(t0))  # fmt: skip
            return dataclasses.replace(sol, counts={**identification_counts(ident), **sol.counts})
        fov = ident.fov_rad if fov_known is None and ident.fov_rad else (fov_known or fov_assumed)
        return solution_of(
            self, points, ident, database=identifier.database, vectors=vectors, fov=fov, k1=k1,
            sigma_px=sigma_px, obs_time=obs_time, image=image, timing=(t0, stages),
        )  # fmt: skip

    def prepare(self) -> None:
        """Build (or load from the cache) the databases the Solver's calls use now, once.

        A batch calls it before its first frame, so that no frame's time holds a load. With a
        sensor, the k-d tree is built and the detector runs on a dark frame of the sensor's
        shape: its lazy imports and work buffers are paid here, not by the first frame. Without
        one, the databases of every range of the unknown-field search are loaded too: a set that
        does not identify at the field given goes on to search the scale through them (a first
        load there held one call of a centroid benchmark 30-40 ms, a hundred times its median).
        The tables mapped from the disk cache are read through
        (:meth:`~starsense.identify.database.IdentificationDatabase.page_in`).
        """
        if self.sensor is not None:
            database = self.identifier(2.0 * self.sensor.half_fov_rad[0]).database
            _ = database.tree
            database.page_in()
            shape = (self.sensor.detector.rows, self.sensor.detector.columns)
            for detector in (self.quick_detector, self.detector):
                if detector is not None:
                    detector(np.zeros(shape, dtype=np.float32))
            return
        known = [] if self.settings.fov_rad is None else [self.identifier(self.settings.fov_rad)]
        for identifier in known + [self.identifier(None, r) for r in self.field_plan()]:
            identifier.database.page_in()

    def solve_file(self, path: str | Path, obs_time=None, *, bayer: str | None = None) -> Solution:
        """Load a frame and solve it (:func:`starsense.solve.frames.solve_frame_file`)."""
        return solve_frame_file(self, path, obs_time, bayer=bayer)
