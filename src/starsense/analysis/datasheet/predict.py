"""The datasheet's predictions: signal, detection, noise-equivalent angle, limit, availability.

Everything here comes from the sensor model and the catalogue, without rendering a frame (but
for the slew-tolerance Monte Carlo of :mod:`starsense.analysis.slew`, which renders single
stars). :mod:`starsense.analysis.datasheet.verify` checks it against rendered frames.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from starsense.analysis.datasheet.field import (
    axis_sigmas,
    field_stars_cam,
    fisher_per_pointing,
    propagated_sigmas,
)
from starsense.analysis.datasheet.noise import CentroidNoise, centroid_noise
from starsense.analysis.datasheet.terms import (
    confusion_px,
    pixel_spatial_error,
    prnu_centroid_px,
)
from starsense.analysis.sensor_detection import limiting_magnitude, slew_grids
from starsense.analysis.slew import last_above
from starsense.photometry.sensitivity import Sensitivity
from starsense.units import DEG

__all__ = [
    "DEFAULT_RATES_RAD_S",
    "StarModel",
    "error_kinds",
    "fastest_rate",
    "limiting_magnitude",
    "nea_at",
    "slew_grids",
]

#: width of the magnitude bins of the catalogue's star counts (the confusion term), mag
_COUNT_BIN_MAG = 0.25


def _confusion(sensor, sens, noise: CentroidNoise, mags: np.ndarray) -> np.ndarray:
    """Confusion (px rms per axis) on the electrons of ``noise``, from the catalogue's counts."""
    mags = mags[np.isfinite(mags)]
    if len(mags) == 0:  # the catalogue ends above the detection limit: nothing unresolved
        return np.zeros(len(noise.electrons))
    edges = np.arange(np.floor(mags.min()), mags.max() + _COUNT_BIN_MAG, _COUNT_BIN_MAG)
    n, edges = np.histogram(mags, bins=edges)
    pixel_rad = sensor.detector.pixel_pitch_m / sensor.optics.focal_length_m
    density = n / (4.0 * np.pi) * pixel_rad**2  # stars per square pixel, sky mean
    flux = sens.electrons(0.5 * (edges[:-1] + edges[1:]))
    return confusion_px(
        noise.electrons,
        np.where(np.isfinite(noise.window_px), noise.window_px, 0.0),
        sigma_px=sensor.detector.psf_sigma_px,
        neighbours=flux,
        density_px2=density,
    )


#: the datasheet's availability rates: at rest and 0.5, 1, 2 deg/s (rad/s)
DEFAULT_RATES_RAD_S = np.array([0.0, 0.5, 1.0, 2.0]) * DEG


def fastest_rate(rates, availability, target: float) -> float | None:
    """Return the fastest rate (from rest) whose availability stays >= ``target``.

    Linear interpolation between the last passing and the first failing rate; None when even
    rest falls short; the top rate when every rate passes.
    """
    return last_above(rates, availability, target)


@dataclass(frozen=True)
class StarModel:
    """Per-star noise of the sensor: photo-electrons -> centroid sigma, bound and bias (px).

    Attributes
    ----------
    sensor : Sensor
    sensitivity : Sensitivity
        Magnitude -> photo-electrons (the rendering's model).
    noise : CentroidNoise
        Centroid noise table of the sensor's centroider.
    pixel_bias : PixelSpatialError or None
        The centroider's sub-pixel bias measured on noiseless renders.
    noise_corner : CentroidNoise or None
        The noise table at the corners' PSF (``optics.psf_sigma_corner_px``); a star's noise
        is interpolated between the two tables as its PSF is (with the square of its distance
        from the centre).
    confusion_px : ndarray or None
        The confusion of fainter catalogue stars inside the centroid window, px rms per axis,
        on the electrons of ``noise`` (:func:`starsense.analysis.datasheet.terms.
        confusion_px`); None without the catalogue's star counts.
    """

    sensor: object
    sensitivity: object
    noise: CentroidNoise
    pixel_bias: object = None
    noise_corner: CentroidNoise | None = None
    confusion_px: np.ndarray | None = None

    @classmethod
    def build(
        cls, sensor, *, model: str, bright_mag: float, faint_mag: float, star_counts=None
    ) -> StarModel:
        """Tabulate the noise from ``bright_mag`` to ``faint_mag`` (V) for ``sensor``.

        ``star_counts``: the V magnitudes of every star of the catalogue the frames hold (to
        its faintest), for the confusion of faint neighbours; None leaves it out.
        """
        sens = Sensitivity.for_sensor(sensor, model)
        e_hi, e_lo = (float(x) for x in sens.electrons(np.array([bright_mag, faint_mag])))
        noise = centroid_noise(sensor, 0.5 * e_lo, 2.0 * e_hi)
        probe = np.geomspace(max(e_lo, 1.0), max(e_hi, 2.0), 5)
        bias = pixel_spatial_error(sensor, probe)
        corner = None
        sc = sensor.optics.psf_sigma_corner_px
        if sc > 0 and sc != sensor.detector.psf_sigma_px:
            wide = sensor.with_(detector=dataclasses.replace(sensor.detector, psf_sigma_px=sc))
            corner = centroid_noise(wide, 0.5 * e_lo, 2.0 * e_hi)
        conf = None
        if star_counts is not None:
            counts = np.asarray(star_counts, dtype=float)
            # the stars below the detection limit: unresolved, they sit in the windows
            conf = _confusion(sensor, sens, noise, counts[counts > faint_mag])
        return cls(sensor, sens, noise, bias, corner, conf)

    def _corner_weight(self, z_cam) -> np.ndarray:
        """Return (r / r_corner)^2 of stars at camera-frame z (r from the detector centre)."""
        det = self.sensor.detector
        z = np.asarray(z_cam, dtype=float)
        r2_px = self.sensor.focal_length_px**2 * (1.0 / z**2 - 1.0)
        corner2 = (0.5 * (det.columns - 1)) ** 2 + (0.5 * (det.rows - 1)) ** 2
        return np.clip(r2_px / corner2, 0.0, 1.0)

    @property
    def pixel_rad(self) -> float:
        """Angle of one pixel at the boresight, rad."""
        return self.sensor.detector.pixel_pitch_m / self.sensor.optics.focal_length_m

    def star_sigmas_rad(self, magnitudes, z_cam, kind: str = "nea") -> np.ndarray:
        """Return each star's 1-sigma direction error, rad.

        ``kind``: "nea" (the centroider's temporal noise), "weight" (the noise the solver
        assumes, whose inverse square weights the star in its attitude fit), "crb" (the
        pixelated-Gaussian bound), "pixel" (the sub-pixel bias as noisy frames meet it, rms
        over pixel phases), "confusion" (fainter catalogue stars in the centroid window),
        "prnu" (the shift the detector's photo-response non-uniformity gives a centroid) or
        "residual" (the distortion calibration's residual). Off-axis stars scale by the
        camera-frame z (the pinhole's angle per pixel, across the radial direction).
        """
        e = self.sensitivity.electrons(np.asarray(magnitudes, dtype=float))
        tables = {"nea": "sigma", "weight": "solver_sigma", "pixel": "bias"}
        if kind in tables:
            px = getattr(self.noise, tables[kind])(e)
            if self.noise_corner is not None:  # the PSF widens to the corners
                t = self._corner_weight(z_cam)
                px = (1.0 - t) * px + t * getattr(self.noise_corner, tables[kind])(e)
        elif kind == "crb":
            px = self.noise.crb(e)
        elif kind == "confusion":
            px = np.zeros(np.shape(e))
            if self.confusion_px is not None:
                px = np.interp(np.log(e), np.log(self.noise.electrons), self.confusion_px)
        elif kind == "prnu":
            px = np.full(np.shape(e), prnu_centroid_px(self.sensor))
        elif kind == "residual":
            px = np.full(np.shape(e), self.sensor.optics.distortion_residual_px)
        else:
            raise ValueError(f"unknown error kind {kind!r}")
        px = np.where(np.isfinite(px), px, np.inf)
        return px * self.pixel_rad * np.asarray(z_cam, dtype=float)


def error_kinds(sensor) -> tuple[str, ...]:
    """Return the per-star kinds of a sensor: noise, bound, bias, and its own rendered errors.

    Parameters
    ----------
    sensor : Sensor

    Returns
    -------
    tuple of str
        ``("nea", "crb", "pixel", "confusion")``, then ``"prnu"`` with a PRNU and
        ``"residual"`` with a distortion calibration residual.
    """
    kinds = ["nea", "crb", "pixel", "confusion"]
    if sensor.detector.prnu_fraction > 0:
        kinds.append("prnu")
    if sensor.optics.distortion_residual_px > 0:
        kinds.append("residual")
    return tuple(kinds)


def nea_at(model: StarModel, fov, matrices, *, vectors, magnitudes, kinds=("nea",), tree=None):
    """Return {kind: (cross, roll)} per attitude, rad, from the stars in the field.

    Parameters
    ----------
    model : StarModel
    fov : RectangularFov
        The sensor's field.
    matrices : ndarray (M, 3, 3)
        Attitudes, ICRS -> camera.
    vectors, magnitudes : ndarray (N, 3), (N,)
        The stars the tracker uses (detected at rest), ICRS.
    kinds : sequence of str
        Per-star error kinds of :meth:`StarModel.star_sigmas_rad`.
    tree : cKDTree, optional
        Built on ``vectors``.

    Returns
    -------
    dict, and the stars in the field per attitude (M,)
    """
    pairs = field_stars_cam(fov, np.asarray(matrices), np.asarray(vectors), tree=tree)
    mags, z = np.asarray(magnitudes)[pairs.star], pairs.v_cam[:, 2]
    # the solver's own weights (its assumed noise), which are not the stars' true noise: a
    # saturated star's centroid is worse than its photons say, and the fit trusts it anyway
    weights = 1.0 / model.star_sigmas_rad(mags, z, "weight") ** 2
    out = {}
    for kind in kinds:
        sigma = model.star_sigmas_rad(mags, z, kind)
        if kind == "crb":
            out[kind] = axis_sigmas(fisher_per_pointing(pairs, 1.0 / sigma**2))
        else:
            out[kind] = propagated_sigmas(pairs, weights, np.where(np.isfinite(sigma), sigma, 0))
    return out, pairs.counts()
