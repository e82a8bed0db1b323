"""The datasheet's predictions: signal, detection, noise-equivalent angle, limit, availability.

Everything here comes from the sensor model and the catalogue, without rendering a frame (but
for the slew-tolerance Monte Carlo of :mod:`starsense.analysis.slew`, which renders single
stars). :mod:`starsense.analysis.datasheet.verify` checks it against rendered frames.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from dataclasses import dataclass

import numpy as np

from starsense.analysis.datasheet.field import (
    axis_sigmas,
    field_stars_cam,
    fisher_per_pointing,
    propagated_sigmas,
)
from starsense.analysis.datasheet.model_noise import (
    model_noise_and_shape,
    zero_pixel_bias,
)
from starsense.analysis.datasheet.noise import CentroidNoise, centroid_noise
from starsense.analysis.datasheet.terms import (
    confusion_px,
    pixel_spatial_error,
    prnu_centroid_px,
)
from starsense.analysis.sensor_detection import limiting_magnitude, slew_grids
from starsense.analysis.slew import last_above
from starsense.attitude.robust import OUTLIER_SIGMA, robust_attitude
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


def _neighbour_classes(sensor, sens, mags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the catalogue's stars as classes: photo-electrons (B,), sky-mean density (px^-2)."""
    mags = mags[np.isfinite(mags)]
    if len(mags) == 0:
        return np.zeros(0), np.zeros(0)
    edges = np.arange(np.floor(mags.min()), mags.max() + _COUNT_BIN_MAG, _COUNT_BIN_MAG)
    n, edges = np.histogram(mags, bins=edges)
    pixel_rad = sensor.detector.pixel_pitch_m / sensor.optics.focal_length_m
    density = n / (4.0 * np.pi) * pixel_rad**2  # stars per square pixel, sky mean
    return sens.electrons(0.5 * (edges[:-1] + edges[1:])), density


def _confusion(sensor, sens, noise: CentroidNoise, mags: np.ndarray) -> np.ndarray:
    """Confusion (px rms per axis) on the electrons of ``noise``, from the catalogue's counts."""
    flux, density = _neighbour_classes(sensor, sens, mags)
    if len(flux) == 0:  # the catalogue ends above the detection limit: nothing unresolved
        return np.zeros(len(noise.electrons))
    return confusion_px(
        noise.electrons,
        np.where(np.isfinite(noise.window_px), noise.window_px, 0.0),
        sigma_px=sensor.detector.psf_sigma_px,
        neighbours=flux,
        density_px2=density,
        reject_px=OUTLIER_SIGMA * noise.solver_sigma_px,  # pulled further, the star is dropped
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
    neighbours : (ndarray, ndarray, ndarray) or None
        The catalogue stars whose streaks blend under slew, as classes: photo-electrons (B,),
        sky-mean density (B,), px^-2, and the share of each one's pull the solver's model
        leaves (B,): 1 for those the solver's catalogue lacks, the catalogue's flux-ratio error
        for those it models; None without the counts.
    refine : {"model", "cog"}
        The solver's last step the prediction is of (:class:`starsense.solve.Solver`).
    shape : (ndarray, ndarray, ndarray) or None
        The model fit's position information's anisotropy on electrons: (electrons, a, c) of
        :func:`~starsense.analysis.datasheet.model_noise.model_noise_and_shape`; None for a
        round PSF and for the centre of gravity.
    """

    sensor: object
    sensitivity: object
    noise: CentroidNoise
    pixel_bias: object = None
    noise_corner: CentroidNoise | None = None
    confusion_px: np.ndarray | None = None
    neighbours: tuple | None = None
    refine: str = "model"
    shape: tuple | None = None

    @classmethod
    def build(
        cls,
        sensor,
        *,
        model: str,
        bright_mag: float,
        faint_mag: float,
        star_counts=None,
        unmodelled=None,
        modelled=None,
        flux_error: float = 0.0,
        refine: str = "model",
    ) -> StarModel:
        """Tabulate the noise from ``bright_mag`` to ``faint_mag`` (V) for ``sensor``.

        ``star_counts``: the V magnitudes of every star of the catalogue the frames hold (to
        its faintest), for the confusion of faint neighbours; None leaves it out.
        ``unmodelled``: the V magnitudes of those the solver's catalogue lacks, whose light in
        a window at rest (:mod:`starsense.solve.box_blends`) or a capsule under slew
        (:func:`starsense.solve.blends.streak_reference`) it does not model; None: all.
        ``modelled``: the V magnitudes of those it models, whose pulls it misses by
        ``flux_error`` of them (the flux ratio its catalogue gives,
        :func:`starsense.analysis.datasheet.catalogue.flux_ratio_error`).
        ``refine``: the solver's last step, "model" (the forward model's fit: its Cramer-Rao
        bound, :mod:`starsense.analysis.datasheet.model_noise`) or "cog" (the windowed centre
        of gravity of flight software, measured on single-star renders).
        """
        sens = Sensitivity.for_sensor(sensor, model)
        e_hi, e_lo = (float(x) for x in sens.electrons(np.array([bright_mag, faint_mag])))

        def table(s):
            if refine == "model":
                return model_noise_and_shape(s, 0.5 * e_lo, 2.0 * e_hi)
            return centroid_noise(s, 0.5 * e_lo, 2.0 * e_hi), None

        noise, shape = table(sensor)
        probe = np.geomspace(max(e_lo, 1.0), max(e_hi, 2.0), 5)
        bias = zero_pixel_bias(probe) if refine == "model" else pixel_spatial_error(sensor, probe)
        corner = None
        sc = sensor.optics.psf_sigma_corner_px
        if sc > 0 and sc != sensor.detector.psf_sigma_px:
            wide = sensor.with_(detector=dataclasses.replace(sensor.detector, psf_sigma_px=sc))
            corner = table(wide)[0]
        conf = near = None
        if star_counts is not None:
            counts = np.asarray(star_counts, dtype=float)
            blends = counts if unmodelled is None else np.asarray(unmodelled, dtype=float)
            # faint stars in the windows: the solver models its catalogue's (box_blends)
            conf = _confusion(sensor, sens, noise, blends[blends > faint_mag])
            flux, rho = _neighbour_classes(sensor, sens, blends)
            share = np.ones(len(flux))
            if modelled is not None and flux_error > 0:
                held = np.asarray(modelled, dtype=float)
                missed = _confusion(sensor, sens, noise, held[held > faint_mag])
                conf = np.hypot(conf, flux_error * missed)
                f_m, rho_m = _neighbour_classes(sensor, sens, held)
                flux, rho = np.append(flux, f_m), np.append(rho, rho_m)
                share = np.append(share, np.full(len(f_m), float(flux_error)))
            near = (flux, rho, share)
        return cls(sensor, sens, noise, bias, corner, conf, near, refine, shape)

    def star_shape(self, magnitudes) -> tuple[np.ndarray, np.ndarray] | None:
        """Return each star's position information's anisotropy ``(a, c)``, or None if round.

        The model fit's (:attr:`shape`, on the star's electrons); the sums it enters are
        :func:`~starsense.analysis.datasheet.field.fisher_per_pointing`'s ``shape``.
        """
        if self.shape is None:
            return None
        grid, a, c = self.shape
        log_e = np.log(self.sensitivity.electrons(np.asarray(magnitudes, dtype=float)))
        return np.interp(log_e, np.log(grid), a), np.interp(log_e, np.log(grid), c)

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


def nea_at(
    model: StarModel,
    fov,
    matrices,
    *,
    vectors,
    magnitudes,
    kinds=("nea",),
    tree=None,
    catalogue=None,
    presence=None,
):
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
    catalogue : ndarray (N, 3), optional
        Each star's database position less its rendered one, ICRS, rad
        (:mod:`starsense.analysis.datasheet.catalogue`): the kind ``"catalogue"``.
    presence : ndarray (N,), optional
        The chance each star is in the fit (:func:`starsense.analysis.datasheet.field.
        fitted_stars`): its information and its errors count by it. Default: always.

    Returns
    -------
    dict, and the stars in the field per attitude (M,)
    """
    pairs = field_stars_cam(fov, np.asarray(matrices), np.asarray(vectors), tree=tree)
    mags, z = np.asarray(magnitudes)[pairs.star], pairs.v_cam[:, 2]
    p = None if presence is None else np.asarray(presence, dtype=float)[pairs.star]
    chance = 1.0 if p is None else p
    # the solver's own weights (its assumed noise), which are not the stars' true noise: a
    # saturated star's centroid is worse than its photons say, and the fit trusts it anyway
    weights = 1.0 / model.star_sigmas_rad(mags, z, "weight") ** 2
    shape = model.star_shape(mags)  # a PSF that is not round: the fit's weights are 2 x 2
    out = {}
    for kind in kinds:
        if kind == "catalogue":  # per star, not per magnitude: each star's own offset
            out[kind] = _catalogue_errors(pairs, matrices, weights, catalogue, presence=p)
            continue
        sigma = model.star_sigmas_rad(mags, z, kind)
        if kind == "crb":
            out[kind] = axis_sigmas(fisher_per_pointing(pairs, chance / sigma**2, shape))
        else:
            error = np.where(np.isfinite(sigma), sigma, 0)
            efficient = kind == "nea" and model.refine == "model"  # its noise: 1 / information
            out[kind] = propagated_sigmas(
                pairs, weights, error, presence=p, shape=shape, efficient=efficient
            )
    return out, pairs.counts()


#: the stars the solver's final fit drops at most (robust_attitude's default)
_MAX_DROP = int(inspect.signature(robust_attitude).parameters["max_drop"].default)


def dropped_stars(pairs, weights, bias_rad) -> np.ndarray:
    """Return the pairs the solver's final fit drops, from their centroids' biases.

    :func:`starsense.attitude.robust.robust_attitude` on the expected centroids: the weighted
    fit of each frame, the residual of every star (its bias less the fitted attitude's share,
    ``b + [r]x dtheta``), and while the worst exceeds ``OUTLIER_SIGMA`` of that star's sigma
    (and more than 3 stars remain) that star is dropped, at most ``max_drop`` per frame. A
    star biased by many of the sigma the solver assumes for it (a saturated streak clipped
    unevenly, a star cut by the frame's edge in a frame kept at the detector's centroids) is
    dropped, as it is from the frames.

    Parameters
    ----------
    pairs : FieldStarsCam
    weights : ndarray (P,)
        The solver's weights, rad^-2.
    bias_rad : ndarray (P, 3)
        Each centroid's bias, camera frame (normal to the star), rad.
    """
    point, r = np.asarray(pairs.point), np.asarray(pairs.v_cam, dtype=float)
    z = np.linalg.norm(bias_rad, axis=1) * np.sqrt(weights)
    out = np.zeros(len(point), dtype=bool)
    for p in np.unique(point[np.nan_to_num(z) > OUTLIER_SIGMA]):
        at = np.flatnonzero((point == p) & (weights > 0) & np.isfinite(z))
        keep = np.ones(len(at), dtype=bool)
        rr, ww, bb = r[at], weights[at], bias_rad[at]
        for _ in range(_MAX_DROP):
            if keep.sum() <= 3:
                break
            wk = np.where(keep, ww, 0.0)
            proj = np.eye(3) - rr[:, :, None] * rr[:, None, :]
            f = np.einsum("i,ijk->jk", wk, proj)
            # the fit: residual b + [r]x dtheta; normal equations F dtheta = -sum w [r]x^T b
            rhs = np.einsum("i,ij->j", wk, np.cross(rr, bb))
            dtheta = np.linalg.lstsq(f, -rhs, rcond=None)[0]
            res = np.linalg.norm(bb + np.cross(dtheta[None, :], rr), axis=1) * np.sqrt(ww)
            res[~keep] = -np.inf
            worst = int(np.argmax(res))
            if res[worst] <= OUTLIER_SIGMA:
                break
            keep[worst] = False
        out[at[~keep]] = True
    return out


def camera_offsets(pairs, matrices, offsets) -> np.ndarray:
    """Return the ICRS offsets (N, 3) of the stars of ``pairs`` in the camera frame (P, 3)."""
    mats = np.asarray(matrices, dtype=float)[pairs.point]
    off = np.einsum("pij,pj->pi", mats, np.asarray(offsets, dtype=float)[pairs.star])
    r = np.asarray(pairs.v_cam, dtype=float)
    return off - np.sum(off * r, axis=1)[:, None] * r  # normal to the star


def _catalogue_errors(
    pairs, matrices, weights, offsets, *, presence=None
) -> tuple[np.ndarray, np.ndarray]:
    """Return the attitude error (cross, roll) per pointing (M,), rad, from the stars' offsets.

    The offset of a star's database position is the same bias in every frame that holds it,
    and the offsets of neighbouring stars are not independent (the two catalogues' frames
    turn against each other by a few mas): the fit's answer to them is computed, not
    modelled, per pointing. The solver's weighted fit of the offsets alone, after its robust
    fit drops the stars they pull past ``OUTLIER_SIGMA`` (:func:`_outliers`): ``dtheta =
    -F^-1 sum_i w_i [r_i]x b_i``, ``F = sum_i w_i (I - r_i r_i^T)``; cross the rms of its x and
    y, roll its z. A star in the fit by chance ``presence`` counts by it (the expected sums).
    """
    off = camera_offsets(pairs, matrices, offsets)
    w = np.where(dropped_stars(pairs, weights, off), 0.0, weights)
    w = w if presence is None else w * presence
    r = np.asarray(pairs.v_cam, dtype=float)
    f = np.zeros((pairs.n_pointings, 3, 3))
    rhs = np.zeros((pairs.n_pointings, 3))
    np.add.at(f, pairs.point, w[:, None, None] * (np.eye(3) - r[:, :, None] * r[:, None, :]))
    np.add.at(rhs, pairs.point, w[:, None] * np.cross(r, off))
    ev = np.linalg.eigvalsh(f)  # fewer than two stars: singular, no attitude
    ok = ev[:, 0] > 1e-12 * ev[:, -1]
    dtheta = np.full((pairs.n_pointings, 3), np.nan)
    dtheta[ok] = -np.linalg.solve(f[ok], rhs[ok][:, :, None])[:, :, 0]
    return np.hypot(dtheta[:, 0], dtheta[:, 1]) / math.sqrt(2.0), np.abs(dtheta[:, 2])
