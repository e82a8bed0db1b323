"""The star-tracker pipeline: a frame in, an attitude out.

image -> background -> detection -> centroids -> unit vectors -> identification -> attitude

The optics are known three ways, from best to least:

* a sensor (preset or TOML): its pinhole + distortion model unprojects the centroids;
* a horizontal field of view (``fov_rad``): a pinhole with the principal point at the centre;
  when the frame does not solve at that field, it is taken as an estimate and the scale is
  searched as below, which refines the field;
* nothing: the centroids are unprojected with a nominal field and the FOV-free pattern hashing
  (edge ratios are scale-invariant) finds the scale, searching fields of 5-30 deg, then 25-70
  deg, then 2.8-6 deg (with the Gaia catalogue when installed;
  :func:`starsense.identify.fields.unknown_field_plan`).

The final attitude is re-estimated from all matched stars with the SVD solution of Wahba's problem
(:mod:`starsense.attitude`), which also gives its covariance (Fialho & Mortari eq. 21) for a
centroid noise of ``centroid_sigma_px``; against the stars' apparent places when the frame's
time is known (:mod:`starsense.catalog.apparent`), so that it is the true ICRS attitude.
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from starsense.errors import InputError
from starsense.geometry.projection import tangent_to_vectors
from starsense.solve.solution import Solution
from starsense.solve.star_noise import cog_sigma_px as _cog_sigma_px
from starsense.units import DEG

__all__ = ["NOMINAL_FOV_RAD", "UNKNOWN_FOV_RANGE_RAD", "Solution", "Solver", "pinhole_vectors"]

#: field range searched when the optics are unknown, rad (5-30, 25-70, then 2.8-6 deg)
UNKNOWN_FOV_RANGE_RAD = (2.8 * DEG, 70.0 * DEG)
#: the field the centroids are unprojected with before the scale is found, rad (15 deg)
NOMINAL_FOV_RAD = 15.0 * DEG
#: PSF sigma of the matched filter when no sensor is given, px (a focused star tracker:
#: 0.7-1.5 px; the filter's gain is within 10 % of optimal for 0.6-1.6 px)
DEFAULT_PSF_SIGMA_PX = 1.0
#: the Solver's accepted range of a given horizontal field, rad (0.5-120 deg)
FOV_RANGE_RAD = (0.5 * DEG, 120.0 * DEG)


class Solver:
    """Configure once (database, detector), then call on frames: ``Solver(...)(image)``.

    Parameters
    ----------
    sensor : str, Path or Sensor, optional
        Sensor preset, TOML path or object: known optics and its detection floors.
    fov_rad : float, optional
        Horizontal field across the image width (pinhole), rad, in [0.5, 120] deg, when no
        sensor is given.
    catalog : str
        Catalogue spec for the database (default: the bundled Hipparcos).
    algorithm : {"hashing", "triangle"}
        Lost-in-space algorithm (triangle needs a known field).
    threshold_sigma : float
        Lit-pixel threshold above the background map, in noise sigmas.
    centroid_sigma_px : float or "snr"
        Centroid noise assumed for the attitude covariance, pixels; "snr" (needs a sensor) uses
        each star's own noise (:func:`_cog_sigma_px`: photon noise plus read noise over its
        centroid window).
    background : {"auto", "known"}
        "auto" estimates a background map and noise (real frames); "known" (needs a sensor)
        subtracts the sensor's bias and applies its detection logic as is (simulated frames).
    apparent : bool
        Fit the attitude to the stars' apparent places when the frame's time is known (default).
    observer_velocity_m_s : array_like, shape (3,), optional
        The observer's velocity relative to the geocentre (orbit), ICRS axes, m/s.
    """

    def __init__(
        self,
        sensor=None,
        fov_rad: float | None = None,
        catalog: str = "hipparcos",
        algorithm: str = "hashing",
        threshold_sigma: float = 5.0,
        centroid_sigma_px: float | str = 0.3,
        background: str = "auto",
        apparent: bool = True,
        observer_velocity_m_s=None,
    ) -> None:
        from starsense._validate import check_scalar, show
        from starsense.sensor import DetectionThresholds, Sensor, load_sensor

        if sensor is not None and fov_rad is not None:
            raise InputError("give sensor or fov_rad, not both")
        if fov_rad is not None:
            fov_rad = check_scalar(fov_rad, "fov_rad", *FOV_RANGE_RAD)
        if algorithm not in ("hashing", "triangle"):
            raise InputError(f"algorithm must be hashing or triangle, got {algorithm!r}")
        if sensor is None and fov_rad is None and algorithm == "triangle":
            raise InputError("the triangle algorithm needs a known field: give sensor or fov_rad")
        if centroid_sigma_px != "snr" and not (
            isinstance(centroid_sigma_px, (int, float)) and centroid_sigma_px > 0
        ):
            raise InputError(
                f"centroid_sigma_px must be > 0 or 'snr', got {show(centroid_sigma_px)}"
            )
        if background not in ("auto", "known"):
            raise InputError(f"background must be 'auto' or 'known', got {background!r}")
        if sensor is None and (background == "known" or centroid_sigma_px == "snr"):
            raise InputError("background='known' and centroid_sigma_px='snr' need a sensor")
        self.background = background
        self.sensor = (
            sensor if (sensor is None or isinstance(sensor, Sensor)) else load_sensor(sensor)
        )
        self.fov_rad = fov_rad
        self.catalog_spec = catalog
        self.algorithm = algorithm
        self.threshold_sigma = threshold_sigma
        self.centroid_sigma_px = centroid_sigma_px
        self.logic = (
            self.sensor.detection
            if self.sensor is not None
            else DetectionThresholds(lit_pixel_counts=1e-6, min_pixels=3, min_integrated_counts=0)
        )
        self._identifiers: dict = {}
        self.apparent = bool(apparent)
        self.observer_velocity_m_s = observer_velocity_m_s
        self._plan = None

    # -- optics -----------------------------------------------------------------------------

    def _unproject(self, x, y, shape, fov_rad=None) -> tuple[np.ndarray, float | None, float]:
        """Return the centroids' unit vectors, the known horizontal FOV and the assumed one.

        The known field is None when it is to be found; the assumed one is the field the
        vectors were computed with. Both in rad. ``fov_rad`` replaces the Solver's field.
        """
        if self.sensor is not None:
            fov = 2.0 * self.sensor.half_fov_rad[0]
            return self.sensor.unproject(x, y), fov, fov
        known = fov_rad if fov_rad is not None else self.fov_rad
        fov = known if known is not None else NOMINAL_FOV_RAD
        return pinhole_vectors(x, y, shape, fov), known, fov

    def _identifier(self, fov_rad: float | None, field_range=None):
        """Return the identifier of a known field or of one range of the unknown-field search."""
        from starsense.identify.fields import identifier_for, unknown_field_plan

        if self._plan is None:
            self._plan = unknown_field_plan(self.catalog_spec)
        if fov_rad is None and field_range is None:
            field_range = self._plan[0]
        key = (self.algorithm, None if fov_rad is None else round(fov_rad, 9), field_range)
        if key not in self._identifiers:
            self._identifiers[key] = identifier_for(
                self.catalog_spec, self.algorithm, fov_rad, field_range
            )
        return self._identifiers[key]

    def _search_fields(self, vectors, flux, fov_assumed):
        """Identify with the field unknown: each range of the plan in turn until one solves."""
        from starsense.identify import identify_ranked
        from starsense.identify.verify import apply_scale

        self._identifier(None)  # makes the plan; its first range is searched first
        for field_range in self._plan:
            identifier = self._identifier(None, field_range)
            nominal = field_range.nominal_fov_rad  # re-unproject at the range's own field
            v = apply_scale(vectors, math.tan(nominal / 2) / math.tan(fov_assumed / 2))
            ident = identify_ranked(identifier, v, flux, None, assumed_fov_rad=nominal)
            if ident.solved:
                break
        return identifier, ident, None

    # -- the pipeline -----------------------------------------------------------------------

    def _detector(self):
        from starsense.detect import StarDetector

        if self.background == "known":
            return StarDetector.for_sensor(self.sensor)
        psf = self.sensor.detector.psf_sigma_px if self.sensor is not None else DEFAULT_PSF_SIGMA_PX
        return StarDetector(
            self.logic,
            "cog",
            background="auto",
            threshold_sigma=self.threshold_sigma,
            matched_filter=True,
            min_snr=self.threshold_sigma,
            psf_sigma_px=psf,
        )

    def _identify(self, vectors, flux, fov_known, fov_assumed):
        """Return (identifier, identification, known field or None after a scale search)."""
        from starsense.identify import identify_ranked

        if fov_known is None:
            return self._search_fields(vectors, flux, fov_assumed)
        identifier = self._identifier(fov_known)
        ident = identify_ranked(identifier, vectors, flux, fov_known)
        if (
            not ident.solved
            and self.sensor is None
            and self.algorithm == "hashing"
            and len(vectors) >= 4  # the 4-star patterns need 4; no scale to search with fewer
        ):
            # a given field is an estimate: search the scale around it, which refines the field
            return self._search_fields(vectors, flux, fov_assumed)
        return identifier, ident, fov_known

    def _reference(self, ref, catalog_ids, obs_time) -> tuple[np.ndarray, dict]:
        """Return the matched stars' reference vectors: apparent places when a time is known."""
        if obs_time is None or not self.apparent:
            return ref, {"applied": False, "reason": "no frame time" if obs_time is None else "off"}
        from starsense.catalog.apparent import apparent_places_of

        p = apparent_places_of(self.catalog_spec, catalog_ids, obs_time, self.observer_velocity_m_s)
        return p.vectors, p.to_dict()

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
        stages: dict[str, float] = {}
        a = np.asarray(image)
        detector = self._detector()
        det = detector(a)
        stages["detect_ms"] = _ms(t0)
        if len(det) == 0:
            return Solution(
                "no_stars", "no star passed the detection logic", time_ms=_ms(t0), stage_ms=stages
            )

        def sigma_px(matched):
            if self.centroid_sigma_px == "snr":
                return _cog_sigma_px(det, matched, self.sensor.detector, detector.margin_px)
            return self.centroid_sigma_px

        return self._solve_points(
            det.x,
            det.y,
            det.integrated_counts,
            a.shape,
            t0,
            stages,
            sigma_px,
            None,
            "detections",
            obs_time,
        )

    def solve_centroids(self, xy, image_size, fov=None, brightness=None) -> Solution:
        """Solve a list of centroids measured by any centroider (no image needed).

        Pixel convention (that of :mod:`starsense.detect`): (0, 0) is the centre of the top-left
        pixel, x runs along the columns (to the right) and y along the rows (down); the image
        spans x in [-0.5, width - 0.5). The optics are the Solver's (sensor or ``fov_rad``),
        or ``fov`` for this call, or unknown (the scale is then searched).

        Parameters
        ----------
        xy : array_like, shape (N, 2)
            Centroids (x = column, y = row), pixels.
        image_size : (int, int)
            Width and height of the image, pixels (columns, rows).
        fov : float, optional
            Horizontal field across the image width (pinhole), rad, in [0.5, 120] deg: for
            this call, in place of the Solver's (not with a sensor).
        brightness : array_like, shape (N,), optional
            Anything that grows with brightness (flux, counts); when omitted the centroids are
            taken as listed brightest first.

        Returns
        -------
        Solution
            The same object as an image solve (``centroids_px`` are the given ones, ``matches``
            index them); "too_few_stars" for fewer than 3 centroids.

        Raises
        ------
        InputError
            Centroids not (N, 2) finite numbers, a bad image size or field, brightness not one
            finite value per centroid, an image size that is not the sensor's.
        """
        from starsense._validate import check_scalar

        t0 = time.perf_counter()
        from starsense.solve.centroids import check_centroids, check_image_size

        pts = check_centroids(xy)
        shape = check_image_size(image_size)
        if fov is not None:
            if self.sensor is not None:
                raise InputError("give fov only to a Solver without a sensor")
            fov = check_scalar(fov, "fov", *FOV_RANGE_RAD)
        if self.sensor is not None:
            det = self.sensor.detector
            if shape != (det.rows, det.columns):
                raise InputError(
                    f"image_size {shape[1]} x {shape[0]} is not the sensor's "
                    f"{det.columns} x {det.rows}"
                )
        if brightness is None:
            flux = np.arange(len(pts), 0, -1, dtype=float)  # as listed: brightest first
        else:
            flux = np.asarray(brightness, dtype=float)
            if flux.shape != (len(pts),) or not np.all(np.isfinite(flux)):
                raise InputError(
                    f"brightness must be {len(pts)} finite numbers (one per centroid), "
                    f"got shape {flux.shape}"
                )
        sigma = self.centroid_sigma_px if self.centroid_sigma_px != "snr" else 0.3
        return self._solve_points(
            pts[:, 0], pts[:, 1], flux, shape, t0, {}, lambda _: sigma, fov, "centroids"
        )

    def _solve_points(
        self, x, y, flux, shape, t0, stages, sigma_px, fov_given, what, obs_time=None, parity=True
    ):
        """Identify centroids (x, y) of an image of ``shape`` and fit the attitude.

        When they do not solve (and are not clutter), their mirror image is tried
        (:func:`starsense.solve.parity.solve_mirrored`, unless ``parity`` is False).
        """
        from starsense.attitude.robust import robust_attitude
        from starsense.geometry.attitude import radec_roll_from_attitude
        from starsense.solve.blends import blend_radius_px, photocentres

        n = len(x)
        if n < 3:
            said = f"{n} centroid(s) given" if what == "centroids" else f"{n} star(s) detected"
            return Solution(
                "too_few_stars",
                f"{said}; 3 are needed",
                n_detections=n,
                time_ms=_ms(t0),
                stage_ms=stages,
            )
        vectors, fov_known, fov_assumed = self._unproject(x, y, shape, fov_given)
        t1 = time.perf_counter()
        self._identifier(fov_known)  # database build or cache load, timed on its own
        stages["database_ms"] = _ms(t1)
        t2 = time.perf_counter()
        identifier, ident, fov_known = self._identify(vectors, flux, fov_known, fov_assumed)
        stages["identify_ms"] = _ms(t2)
        if not ident.solved:
            status, message = ident.status, ident.message
            limit = max_candidates(shape)
            if parity and n <= limit:  # a mirrored frame fails identification: flip, retry
                from starsense.solve.parity import solve_mirrored

                mirrored = solve_mirrored(
                    x,
                    y,
                    flux,
                    shape,
                    lambda mx, my, f: self._solve_points(
                        mx,
                        my,
                        f,
                        shape,
                        t0,
                        stages,
                        sigma_px,
                        fov_given,
                        what,
                        obs_time,
                        parity=False,
                    ),
                )
                if mirrored is not None:
                    return mirrored
            if n > limit:
                status = "too_many_candidates"
                message = (
                    f"{n} candidates, more than a frame of {shape[1]} x {shape[0]} "
                    f"pixels can hold as stars ({limit}): noise or clutter passed the detection "
                    f"(then: {message})"
                )
            return Solution(status, message, n_detections=n, time_ms=_ms(t0), stage_ms=stages)
        # final attitude from all matches, with its covariance
        t3 = time.perf_counter()
        fov = ident.fov_rad if fov_known is None and ident.fov_rad else (fov_known or fov_assumed)
        if fov_known is None:  # re-unproject with the field found
            vectors = pinhole_vectors(x, y, shape, fov)
        matched = np.asarray(ident.detection_index)
        db = identifier.database
        plain = db.vectors[np.asarray(ident.catalog_index)]
        ref, apparent = self._reference(plain, ident.catalog_id, obs_time)
        if self.sensor is not None:  # blended close doubles: their photocentre, not one star
            radius = blend_radius_px(self.sensor.detector.psf_sigma_px) * fov / shape[1]
            ref = ref + photocentres(db.vectors, db.mags, db.tree, ident.catalog_index, radius)
            ref = ref - plain
            ref /= np.linalg.norm(ref, axis=1)[:, None]
        pixel_rad = fov / shape[1]
        att, _ = robust_attitude(vectors[matched], ref, sigma_px(matched) * pixel_rad)
        stages["attitude_ms"] = _ms(t3)
        ra, dec, roll = radec_roll_from_attitude(att.rotation)
        return Solution(
            "solved",
            f"{ident.n_matches} of {n} {what} matched ({ident.algorithm})",
            ra_rad=float(ra),
            dec_rad=float(dec),
            roll_rad=float(roll),
            fov_rad=float(fov),
            n_detections=n,
            n_matched=int(ident.n_matches),
            rmse_rad=float(att.residual_rms_rad),
            false_match_probability=float(ident.false_match_probability),
            sigma_rad=tuple(float(s) for s in att.sigma_axes_rad),
            time_ms=_ms(t0),
            stage_ms=stages,
            rotation=att.rotation,
            matches=tuple(
                (int(d), int(c))
                for d, c in zip(ident.detection_index, ident.catalog_id, strict=True)
            ),
            centroids_px=np.column_stack([x, y]),
            image_shape=tuple(shape),
            focal_px=(
                self.sensor.focal_length_px
                if self.sensor is not None
                else shape[1] / 2.0 / math.tan(fov / 2.0)
            ),
            apparent=apparent,
            sensor=self.sensor,
        )

    def prepare(self) -> None:
        """Build (or load from the cache) the database of the Solver's field now, once.

        A batch calls it before its first frame, so that no frame's time holds the load.
        """
        if self.sensor is not None:
            self._identifier(2.0 * self.sensor.half_fov_rad[0])
        else:
            self._identifier(self.fov_rad)

    def track(self, image, prior=None):
        """Track a frame from a prior attitude (:func:`starsense.solve.track.track_frame`).

        Falls back to lost-in-space when the prior's match fails or is ambiguous, and says so;
        returns a :class:`~starsense.solve.track.TrackSolution`.
        """
        from starsense.solve.track import track_frame

        return track_frame(self, image, prior)

    def solve_file(self, path: str | Path, obs_time=None) -> Solution:
        """Load a frame (:func:`starsense.solve.frames.load_image`) and solve it.

        The frame's time is ``obs_time`` if given, else its FITS DATE-OBS or EXIF
        DateTimeOriginal / DateTime (:func:`starsense.solve.frames.frame_time`), else unknown.
        """
        from starsense.solve.frames import frame_time, load_image

        image = load_image(path)  # first: its checks (size, header) come before any other read
        source = "obs_time"
        if obs_time is None:
            obs_time, source = frame_time(path)
        sol = self(image, obs_time)
        if sol.apparent is not None and sol.apparent.get("applied"):
            sol = dataclasses.replace(sol, apparent={**sol.apparent, "time_source": source})
        return sol


def pinhole_vectors(x, y, shape, fov_rad: float) -> np.ndarray:
    """Return camera-frame unit vectors of pixel positions seen through a pinhole.

    The horizontal field across the image width is ``fov_rad``, the principal point at the image
    centre (pixel-centre convention); the gnomonic inverse is
    :func:`starsense.geometry.projection.tangent_to_vectors`.

    Parameters
    ----------
    x, y : array_like, shape (N,)
        Column and row of each position, pixels.
    shape : (int, int)
        Rows, columns of the image.
    fov_rad : float
        Horizontal field, rad.

    Returns
    -------
    ndarray, shape (N, 3)
    """
    rows, cols = shape
    f_px = cols / 2.0 / math.tan(fov_rad / 2.0)
    u = (np.asarray(x, dtype=float) - (cols - 1) / 2.0) / f_px
    w = (np.asarray(y, dtype=float) - (rows - 1) / 2.0) / f_px
    return tangent_to_vectors(np.column_stack([u, w]))


def max_candidates(shape) -> int:
    """Return the most detections a frame of ``shape`` can hold as stars.

    One per 1,000 pixels, at least 500: 786 for a 1024 x 768 frame, where the ESA frames give
    22-313 (matched filter, no known optics); real stars closer than ~30 pixels on average
    blend, and identification uses only the brightest tens.
    """
    return max(500, int(shape[0]) * int(shape[1]) // 1000)


def _ms(t0: float) -> float:
    return (time.perf_counter() - t0) * 1e3
