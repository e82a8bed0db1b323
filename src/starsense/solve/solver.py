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
centroid noise of ``centroid_sigma_px``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from starsense._io import atomic_path
from starsense.errors import InputError
from starsense.geometry.projection import tangent_to_vectors
from starsense.units import DEG, RAD_TO_ARCSEC

__all__ = ["NOMINAL_FOV_RAD", "UNKNOWN_FOV_RANGE_RAD", "Solution", "Solver", "pinhole_vectors"]

#: field range searched when the optics are unknown, rad (5-30, 25-70, then 2.8-6 deg)
UNKNOWN_FOV_RANGE_RAD = (2.8 * DEG, 70.0 * DEG)
#: the field the centroids are unprojected with before the scale is found, rad (15 deg)
NOMINAL_FOV_RAD = 15.0 * DEG
#: the Solver's accepted range of a given horizontal field, rad (0.5-120 deg)
FOV_RANGE_RAD = (0.5 * DEG, 120.0 * DEG)


def _deg(angle_rad: float | None) -> float | None:
    return None if angle_rad is None else float(np.degrees(angle_rad))


@dataclass(frozen=True)
class Solution:
    """The answer for one frame, with what is needed to judge it.

    ``status`` is "solved" or says why not ("no_stars", "too_few_stars", "no_match", ...);
    angles follow :mod:`starsense.geometry.attitude` (roll as in the ESA reference.json). The
    angles are stored in radians; ``ra_deg``, ``rmse_arcsec`` ... give them in the units of the
    command line and of :meth:`to_dict`.

    Attributes
    ----------
    status, message : str
        Outcome, and a sentence about it.
    ra_rad, dec_rad, roll_rad : float or None
        Boresight and roll of the attitude, rad.
    fov_rad : float or None
        Horizontal field across the image width, rad (given, or found by the scale search).
    n_detections, n_matched : int
        Stars detected, and identified.
    rmse_rad : float or None
        Rms residual of the matched stars after the fit, rad.
    false_match_probability : float or None
        Probability that the identification is a chance match.
    sigma_rad : tuple of 3 float or None
        1-sigma attitude error about the camera x, y (cross-boresight) and z (roll) axes, rad.
    time_ms : float
        Wall time of the whole solve, ms; ``stage_ms`` per stage.
    rotation : Rotation or None
        The attitude, ICRS -> camera.
    matches : tuple of (int, int)
        (detection index, catalogue id) of every matched star.
    centroids_px : ndarray, shape (N, 2) or None
        Detected centroids (x = column, y = row), pixels.
    image_shape : (int, int) or None
        Rows, columns of the frame.
    focal_px : float or None
        Focal length, pixels.
    """

    status: str
    message: str = ""
    ra_rad: float | None = None
    dec_rad: float | None = None
    roll_rad: float | None = None
    fov_rad: float | None = None
    n_detections: int = 0
    n_matched: int = 0
    rmse_rad: float | None = None
    false_match_probability: float | None = None
    sigma_rad: tuple[float, float, float] | None = None
    time_ms: float = 0.0
    stage_ms: dict = field(default_factory=dict)
    rotation: Rotation | None = field(default=None, repr=False)
    matches: tuple[tuple[int, int], ...] = field(default=(), repr=False)
    centroids_px: np.ndarray | None = field(default=None, repr=False)
    image_shape: tuple[int, int] | None = None
    focal_px: float | None = None

    @property
    def ra_deg(self) -> float | None:
        """Right ascension of the boresight, deg."""
        return _deg(self.ra_rad)

    @property
    def dec_deg(self) -> float | None:
        """Declination of the boresight, deg."""
        return _deg(self.dec_rad)

    @property
    def roll_deg(self) -> float | None:
        """Roll about the boresight, deg."""
        return _deg(self.roll_rad)

    @property
    def fov_deg(self) -> float | None:
        """Horizontal field across the image width, deg."""
        return _deg(self.fov_rad)

    @property
    def rmse_arcsec(self) -> float | None:
        """Rms residual of the matched stars, arcsec."""
        return None if self.rmse_rad is None else float(self.rmse_rad * RAD_TO_ARCSEC)

    @property
    def sigma_arcsec(self) -> tuple[float, float, float] | None:
        """1-sigma attitude error about the camera x, y and z axes, arcsec."""
        if self.sigma_rad is None:
            return None
        return tuple(float(s * RAD_TO_ARCSEC) for s in self.sigma_rad)

    def wcs(self):
        """Return an astropy TAN WCS of the solved frame (FITS 1-based pixels).

        A pinhole frame is exactly a gnomonic (TAN) projection: with the camera axes x, y in ICRS
        and east, north at the boresight, the CD matrix is (180/pi) / f_px
        [[e.x, e.y], [n.x, n.y]]. Lens distortion, where the sensor has any, is not carried
        (no SIP terms).

        Returns
        -------
        astropy.wcs.WCS

        Raises
        ------
        InputError
            The frame is not solved.
        """
        from astropy.wcs import WCS

        from starsense.geometry.attitude import east_north

        if not self.solved:
            raise InputError(f"no WCS for an unsolved frame (status {self.status})")
        rows, cols = self.image_shape
        axes = self.rotation.as_matrix()  # rows: camera x, y, z in ICRS
        east, north = east_north(np.radians(self.ra_deg), np.radians(self.dec_deg))
        cd = np.degrees(1.0 / self.focal_px) * np.array(
            [[east @ axes[0], east @ axes[1]], [north @ axes[0], north @ axes[1]]]
        )
        w = WCS(naxis=2)
        w.wcs.ctype = ["RA---TAN", "DEC--TAN"]
        w.wcs.crval = [self.ra_deg, self.dec_deg]
        w.wcs.crpix = [(cols - 1) / 2.0 + 1.0, (rows - 1) / 2.0 + 1.0]
        w.wcs.cd = cd
        w.wcs.radesys = "ICRS"
        w.pixel_shape = (cols, rows)
        return w

    def write_wcs(self, path: str | Path) -> Path:
        """Write the WCS as a FITS header (no data), atomically (:mod:`starsense._io`).

        Parameters
        ----------
        path : path-like
            The FITS file to create or replace; its directory must exist.

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        from astropy.io import fits

        path = Path(path)
        header = self.wcs().to_header()
        header["COMMENT"] = "starsense solution: " + self.message
        with atomic_path(path, suffix=".tmp") as tmp:
            fits.PrimaryHDU(header=header).writeto(tmp, overwrite=True)
        return path

    @property
    def solved(self) -> bool:
        """Whether the frame solved."""
        return self.status == "solved"

    def to_dict(self) -> dict:
        """Return the solution as JSON-ready values (degrees and arcseconds, as the CLI prints)."""
        sigma = self.sigma_arcsec
        return {
            "status": self.status,
            "message": self.message,
            "ra_deg": self.ra_deg,
            "dec_deg": self.dec_deg,
            "roll_deg": self.roll_deg,
            "fov_deg": self.fov_deg,
            "n_detections": self.n_detections,
            "n_matched": self.n_matched,
            "rmse_arcsec": self.rmse_arcsec,
            "false_match_probability": self.false_match_probability,
            "sigma_arcsec": None if sigma is None else list(sigma),
            "time_ms": self.time_ms,
            "stage_ms": self.stage_ms,
        }


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
        self._plan = None

    # -- optics -----------------------------------------------------------------------------

    def _unproject(self, x, y, shape) -> tuple[np.ndarray, float | None, float]:
        """Return the centroids' unit vectors, the known horizontal FOV and the assumed one.

        The known field is None when it is to be found; the assumed one is the field the
        vectors were computed with. Both in rad.
        """
        if self.sensor is not None:
            fov = 2.0 * self.sensor.half_fov_rad[0]
            return self.sensor.unproject(x, y), fov, fov
        fov = self.fov_rad if self.fov_rad is not None else NOMINAL_FOV_RAD
        return pinhole_vectors(x, y, shape, fov), self.fov_rad, fov

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
        return StarDetector(
            self.logic, "cog", background="auto", threshold_sigma=self.threshold_sigma
        )

    def _identify(self, vectors, flux, fov_known, fov_assumed):
        """Return (identifier, identification, known field or None after a scale search)."""
        from starsense.identify import identify_ranked

        if fov_known is None:
            return self._search_fields(vectors, flux, fov_assumed)
        identifier = self._identifier(fov_known)
        ident = identify_ranked(identifier, vectors, flux, fov_known)
        if not ident.solved and self.sensor is None and self.algorithm == "hashing":
            # a given field is an estimate: search the scale around it, which refines the field
            return self._search_fields(vectors, flux, fov_assumed)
        return identifier, ident, fov_known

    def __call__(self, image) -> Solution:
        """Solve one frame: detect, identify and estimate the attitude with its covariance.

        Parameters
        ----------
        image : array_like, shape (rows, columns)
            The frame, counts.

        Returns
        -------
        Solution
            Solved, or the reason why not (no exception for a frame that does not solve).
        """
        from starsense.attitude import estimate_attitude
        from starsense.geometry.attitude import radec_roll_from_attitude

        t0 = time.perf_counter()
        stages: dict[str, float] = {}
        a = np.asarray(image)
        detector = self._detector()
        det = detector(a)
        stages["detect_ms"] = _ms(t0)
        if len(det) == 0:
            return Solution("no_stars", "no star passed the detection logic", time_ms=_ms(t0),
                            stage_ms=stages)  # fmt: skip
        if len(det) < 3:
            return Solution("too_few_stars", f"{len(det)} star(s) detected; 3 are needed",
                            n_detections=len(det), time_ms=_ms(t0), stage_ms=stages)  # fmt: skip
        vectors, fov_known, fov_assumed = self._unproject(det.x, det.y, a.shape)
        t1 = time.perf_counter()
        self._identifier(fov_known)  # database build or cache load, timed on its own
        stages["database_ms"] = _ms(t1)
        t2 = time.perf_counter()
        identifier, ident, fov_known = self._identify(
            vectors, det.integrated_counts, fov_known, fov_assumed
        )
        stages["identify_ms"] = _ms(t2)
        if not ident.solved:
            return Solution(ident.status, ident.message, n_detections=len(det), time_ms=_ms(t0),
                            stage_ms=stages)  # fmt: skip
        # final attitude from all matches, with its covariance
        t3 = time.perf_counter()
        fov = ident.fov_rad if fov_known is None and ident.fov_rad else (fov_known or fov_assumed)
        if fov_known is None:  # re-unproject with the field found
            vectors = pinhole_vectors(det.x, det.y, a.shape, fov)
        matched = np.asarray(ident.detection_index)
        ref = identifier.database.vectors[np.asarray(ident.catalog_index)]
        if self.centroid_sigma_px == "snr":
            sigma_px = _cog_sigma_px(det, matched, self.sensor.detector, detector.margin_px)
        else:
            sigma_px = self.centroid_sigma_px
        pixel_rad = fov / a.shape[1]
        att = estimate_attitude(vectors[matched], ref, sigma_px * pixel_rad, method="svd")
        stages["attitude_ms"] = _ms(t3)
        ra, dec, roll = radec_roll_from_attitude(att.rotation)
        return Solution(
            "solved",
            f"{ident.n_matches} of {len(det)} detections matched ({ident.algorithm})",
            ra_rad=float(ra),
            dec_rad=float(dec),
            roll_rad=float(roll),
            fov_rad=float(fov),
            n_detections=len(det),
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
            centroids_px=np.column_stack([det.x, det.y]),
            image_shape=a.shape,
            focal_px=(
                self.sensor.focal_length_px
                if self.sensor is not None
                else a.shape[1] / 2.0 / math.tan(fov / 2.0)
            ),
        )

    def solve_file(self, path: str | Path) -> Solution:
        """Load a frame (:func:`starsense.solve.frames.load_image`) and solve it."""
        from starsense.solve.frames import load_image

        return self(load_image(path))


def _cog_sigma_px(det, index, detector, margin_px: int) -> np.ndarray:
    """Return the per-axis noise of a centre-of-gravity centroid, pixels, of detections ``index``.

    Photon noise: sigma_psf^2 / N_e (N_e = integrated counts / gain). Read noise: each pixel of
    the CoG window adds sigma_read^2 (x - x_c)^2 / N_e^2; over a w x h window centred on the star
    the sum of (x - x_c)^2 is h w (w^2 - 1) / 12 (the mean of the two axes is used).
    """
    n_e = np.maximum(det.integrated_counts[index] / detector.gain_counts_per_e, 1.0)
    r0, r1, c0, c1 = det.bbox[index].T
    w = (c1 - c0 + 2 * margin_px).astype(float)
    h = (r1 - r0 + 2 * margin_px).astype(float)
    spread = 0.5 * (h * w * (w**2 - 1) + w * h * (h**2 - 1)) / 12.0
    var = detector.psf_sigma_px**2 / n_e + detector.read_noise_e**2 * spread / n_e**2
    return np.sqrt(var)


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


def _ms(t0: float) -> float:
    return (time.perf_counter() - t0) * 1e3
