"""The star-tracker pipeline: a frame in, an attitude out.

image -> background -> detection -> centroids -> unit vectors -> identification -> attitude

The optics are known three ways, from best to least:

* a sensor (preset or TOML): its pinhole + distortion model unprojects the centroids;
* a horizontal field of view (``fov_deg``): a pinhole with the principal point at the centre;
  when the frame does not solve at that field, it is taken as an estimate and the scale is
  searched (5-30 deg), which refines the field;
* nothing: the centroids are unprojected with a nominal field and the FOV-free pattern hashing
  (edge ratios are scale-invariant) finds the scale, searching fields of 5-30 deg.

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

from starsense.errors import InputError

ARCSEC_PER_RAD = 180.0 / math.pi * 3600.0
#: field range searched when the optics are unknown, deg (issue 5)
UNKNOWN_FOV_RANGE_DEG = (5.0, 30.0)
#: the field the centroids are unprojected with before the scale is found, deg
NOMINAL_FOV_DEG = 15.0


@dataclass(frozen=True)
class Solution:
    """The answer for one frame, with what is needed to judge it.

    ``status`` is "solved" or says why not ("no_stars", "too_few_stars", "no_match", ...);
    angles follow :mod:`starsense.geometry.attitude` (roll as in the ESA reference.json).
    """

    status: str
    message: str = ""
    ra_deg: float | None = None
    dec_deg: float | None = None
    roll_deg: float | None = None
    fov_deg: float | None = None
    n_detections: int = 0
    n_matched: int = 0
    rmse_arcsec: float | None = None
    false_match_probability: float | None = None
    sigma_arcsec: tuple[float, float, float] | None = None
    time_ms: float = 0.0
    stage_ms: dict = field(default_factory=dict)
    rotation: Rotation | None = field(default=None, repr=False)
    matches: tuple[tuple[int, int], ...] = field(default=(), repr=False)
    centroids_px: np.ndarray | None = field(default=None, repr=False)
    image_shape: tuple[int, int] | None = None
    focal_px: float | None = None

    def wcs(self):
        """An astropy TAN WCS of the solved frame (FITS 1-based pixels).

        A pinhole frame is exactly a gnomonic (TAN) projection: with the camera axes x, y in ICRS
        and east, north at the boresight, the CD matrix is (180/pi) / f_px
        [[e.x, e.y], [n.x, n.y]]. Lens distortion, where the sensor has any, is not carried
        (no SIP terms).
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

    def write_wcs(self, path) -> Path:
        """Write the WCS as a FITS header (no data), atomically."""
        import os
        import tempfile

        from astropy.io import fits

        path = Path(path)
        header = self.wcs().to_header()
        header["COMMENT"] = "starsense solution: " + self.message
        with tempfile.NamedTemporaryFile(dir=path.parent or ".", suffix=".tmp", delete=False) as f:
            tmp = f.name
        try:
            fits.PrimaryHDU(header=header).writeto(tmp, overwrite=True)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @property
    def solved(self) -> bool:
        return self.status == "solved"

    def to_dict(self) -> dict:
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
            "sigma_arcsec": None if self.sigma_arcsec is None else list(self.sigma_arcsec),
            "time_ms": self.time_ms,
            "stage_ms": self.stage_ms,
        }


class Solver:
    """Configure once (database, detector), then call on frames: ``Solver(...)(image)``.

    Parameters
    ----------
    sensor : str, Path or Sensor, optional
        Sensor preset, TOML path or object: known optics and its detection floors.
    fov_deg : float, optional
        Horizontal field across the image width (pinhole), when no sensor is given.
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
        fov_deg: float | None = None,
        catalog: str = "hipparcos",
        algorithm: str = "hashing",
        threshold_sigma: float = 5.0,
        centroid_sigma_px: float | str = 0.3,
        background: str = "auto",
    ) -> None:
        from starsense.sensor import DetectionThresholds, Sensor, load_sensor

        if sensor is not None and fov_deg is not None:
            raise InputError("give --sensor or --fov-deg, not both")
        if fov_deg is not None and not (0.5 <= fov_deg <= 120.0):
            raise InputError(f"--fov-deg must be within [0.5, 120] deg, got {fov_deg}")
        if algorithm not in ("hashing", "triangle"):
            raise InputError(f"algorithm must be hashing or triangle, got {algorithm!r}")
        if sensor is None and fov_deg is None and algorithm == "triangle":
            raise InputError(
                "the triangle algorithm needs a known field: give --sensor or --fov-deg"
            )
        if centroid_sigma_px != "snr" and not (
            isinstance(centroid_sigma_px, (int, float)) and centroid_sigma_px > 0
        ):
            raise InputError(f"centroid_sigma_px must be > 0 or 'snr', got {centroid_sigma_px!r}")
        if background not in ("auto", "known"):
            raise InputError(f"background must be 'auto' or 'known', got {background!r}")
        if sensor is None and (background == "known" or centroid_sigma_px == "snr"):
            raise InputError("background='known' and centroid_sigma_px='snr' need a sensor")
        self.background = background
        self.sensor = (
            sensor if (sensor is None or isinstance(sensor, Sensor)) else load_sensor(sensor)
        )
        self.fov_deg = fov_deg
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

    # -- optics -----------------------------------------------------------------------------

    def _unproject(self, x, y, shape) -> tuple[np.ndarray, float | None, float]:
        """Unit vectors of the centroids, the known horizontal FOV (rad, or None) and the field
        the vectors assume (rad).
        """
        if self.sensor is not None:
            fov = 2.0 * self.sensor.half_fov_rad[0]
            return self.sensor.unproject(x, y), fov, fov
        fov = math.radians(self.fov_deg if self.fov_deg is not None else NOMINAL_FOV_DEG)
        return pinhole_vectors(x, y, shape, fov), (fov if self.fov_deg is not None else None), fov

    def _identifier(self, fov_rad: float | None):
        from starsense.catalog import load_catalog
        from starsense.identify import HashIdentifier, TriangleIdentifier, build_database

        key = (self.algorithm, None if fov_rad is None else round(fov_rad, 9))
        if key not in self._identifiers:
            cat = load_catalog(self.catalog_spec)
            if fov_rad is None:
                lo, hi = (math.radians(v) for v in UNKNOWN_FOV_RANGE_DEG)
                db = build_database(cat, hi, lo, patterns_per_field=50)
            else:
                db = build_database(cat, fov_rad)
            cls = HashIdentifier if self.algorithm == "hashing" else TriangleIdentifier
            self._identifiers[key] = cls(db)
        return self._identifiers[key]

    # -- the pipeline -----------------------------------------------------------------------

    def __call__(self, image) -> Solution:
        from starsense.attitude import estimate_attitude
        from starsense.detect import StarDetector
        from starsense.geometry.attitude import radec_roll_from_attitude
        from starsense.identify import identify_ranked

        t0 = time.perf_counter()
        stages: dict[str, float] = {}
        a = np.asarray(image)
        if self.background == "known":
            detector = StarDetector.for_sensor(self.sensor)
        else:
            detector = StarDetector(
                self.logic, "cog", background="auto", threshold_sigma=self.threshold_sigma
            )
        det = detector(a)
        stages["detect_ms"] = (time.perf_counter() - t0) * 1e3
        if len(det) == 0:
            return Solution("no_stars", "no star passed the detection logic", time_ms=_ms(t0),
                            stage_ms=stages)  # fmt: skip
        if len(det) < 3:
            return Solution("too_few_stars", f"{len(det)} star(s) detected; 3 are needed",
                            n_detections=len(det), time_ms=_ms(t0), stage_ms=stages)  # fmt: skip
        vectors, fov_known, fov_assumed = self._unproject(det.x, det.y, a.shape)
        t1 = time.perf_counter()
        identifier = self._identifier(fov_known)
        stages["database_ms"] = (time.perf_counter() - t1) * 1e3
        t2 = time.perf_counter()
        flux = det.integrated_counts
        if fov_known is None:
            ident = identify_ranked(identifier, vectors, flux, None, assumed_fov_rad=fov_assumed)
        else:
            ident = identify_ranked(identifier, vectors, flux, fov_known)
            if not ident.solved and self.sensor is None and self.algorithm == "hashing":
                # --fov-deg is an estimate: search the scale around it, which refines the field
                fov_known = None
                identifier = self._identifier(None)
                ident = identify_ranked(
                    identifier, vectors, flux, None, assumed_fov_rad=fov_assumed
                )
        stages["identify_ms"] = (time.perf_counter() - t2) * 1e3
        if not ident.solved:
            return Solution(ident.status, ident.message, n_detections=len(det), time_ms=_ms(t0),
                            stage_ms=stages)  # fmt: skip
        # final attitude from all matches, with its covariance
        t3 = time.perf_counter()
        fov = ident.fov_rad if fov_known is None and ident.fov_rad else (fov_known or fov_assumed)
        if fov_known is None:  # re-unproject with the field found
            vectors = pinhole_vectors(det.x, det.y, a.shape, fov)
        pixel_rad = fov / a.shape[1]
        matched = np.asarray(ident.detection_index)
        body = vectors[matched]
        ref = identifier.database.vectors[np.asarray(ident.catalog_index)]
        if self.centroid_sigma_px == "snr":
            sigma_px = _cog_sigma_px(det, matched, self.sensor.detector, detector.margin_px)
        else:
            sigma_px = self.centroid_sigma_px
        att = estimate_attitude(body, ref, sigma_px * pixel_rad, method="svd")
        stages["attitude_ms"] = (time.perf_counter() - t3) * 1e3
        ra, dec, roll = radec_roll_from_attitude(att.rotation)
        return Solution(
            "solved",
            f"{ident.n_matches} of {len(det)} detections matched ({ident.algorithm})",
            ra_deg=float(np.degrees(ra)),
            dec_deg=float(np.degrees(dec)),
            roll_deg=float(np.degrees(roll)),
            fov_deg=float(np.degrees(fov)),
            n_detections=len(det),
            n_matched=int(ident.n_matches),
            rmse_arcsec=float(att.residual_rms_rad * ARCSEC_PER_RAD),
            false_match_probability=float(ident.false_match_probability),
            sigma_arcsec=tuple(float(s * ARCSEC_PER_RAD) for s in att.sigma_axes_rad),
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
        from starsense.solve.frames import load_image

        return self(load_image(path))


def _cog_sigma_px(det, index, detector, margin_px: int) -> np.ndarray:
    """Per-axis noise of a centre-of-gravity centroid, pixels, for the detections ``index``.

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
    """Camera-frame unit vectors of pixel positions for a pinhole whose horizontal field across
    the image width is ``fov_rad``, principal point at the image centre (pixel-centre convention).
    """
    rows, cols = shape
    f_px = cols / 2.0 / math.tan(fov_rad / 2.0)
    u = (np.asarray(x, dtype=float) - (cols - 1) / 2.0) / f_px
    w = (np.asarray(y, dtype=float) - (rows - 1) / 2.0) / f_px
    v = np.column_stack([u, w, np.ones_like(u)])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _ms(t0: float) -> float:
    return (time.perf_counter() - t0) * 1e3
