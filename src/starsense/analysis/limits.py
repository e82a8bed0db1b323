"""The physical limit of star-sensor attitude accuracy (Fialho & Mortari 2019).

An ideal sensor of diameter D, exposing for t, limited only by diffraction and photon noise:

* per-star centroid Fisher information F_i = 12 zeta(5) pi^4 k^5 / (h^5 c^4) D^4 t C_i T_i^5
  (eq. 19), or eq. 17 integrated numerically over a passband x QE, or over a measured spectrum;
* attitude Fisher matrix F = sum_i F_i (I - r_i r_i^T) (eq. 21), covariance P = F^-1 (eq. 20);
* theta_rms = sqrt(tr P) (eq. 22) = G D^-2 t^-1/2 (eqs. 23-24).

Kernels are plain functions on NumPy arrays (no I/O), shared with the distributed path.
Stars are carried by :class:`BlackBodyStars`: unit vectors, temperatures, dilutions and the
catalogue magnitude used to rank them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# the attitude Fisher matrix, covariance and theta (eqs. 20-22) live with the attitude stage
from starsense.attitude.covariance import covariance, fisher_matrix, theta_rms
from starsense.errors import InputError, SingularGeometryError
from starsense.geometry.attitude import east_north, vectors_to_radec
from starsense.photometry.blackbody import (
    BOLTZMANN_J_K,
    PLANCK_J_S,
    SPEED_OF_LIGHT_M_S,
    ZETA5,
    photons_per_wavelength,
    total_photons,
)
from starsense.photometry.colour import COLOUR_SYSTEMS, ColourModel

#: 12 zeta(5) pi^4 k^5 / (h^5 c^4): eq. 19's constant, in K^-5 m^-4 s^-1 rad^-2
FISHER_CONSTANT = (
    12.0 * ZETA5 * np.pi**4 * BOLTZMANN_J_K**5 / (PLANCK_J_S**5 * SPEED_OF_LIGHT_M_S**4)
)

#: the paper's interval for G, rad m^2 s^1/2 (sec. 3.3)
G_PAPER_INTERVAL = (7e-15, 1e-13)
#: stars in the Galaxy used for the paper's extrapolation (sec. 3.3)
N_GALAXY = 3e11


def check_aperture(diameter_m: float, exposure_s: float) -> None:
    """Raise InputError unless D > 0 and t > 0 are finite."""
    for name, value in (("diameter_m", diameter_m), ("exposure_s", exposure_s)):
        if not np.isfinite(value) or value <= 0:
            raise InputError(f"{name} must be a finite number > 0, got {value!r}")


def centroid_fisher(dilution, temperature_k, diameter_m: float = 1.0, exposure_s: float = 1.0):
    """Per-star centroid Fisher information, closed form (Fialho & Mortari 2019, eq. 19).

    Parameters
    ----------
    dilution : array (N,)
        Dilution factors C.
    temperature_k : array (N,)
        Black-body temperatures, K.
    diameter_m, exposure_s : float
        Aperture D (m) and exposure t (s).

    Returns
    -------
    array (N,)
        F_i = 1 / sigma_min,i^2 in rad^-2.
    """
    check_aperture(diameter_m, exposure_s)
    t = np.asarray(temperature_k, dtype=float)
    return FISHER_CONSTANT * diameter_m**4 * exposure_s * np.asarray(dilution) * t**5


def centroid_fisher_numeric(
    dilution,
    temperature_k,
    wavelength_m,
    response=None,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
):
    """Per-star centroid Fisher information by integrating eq. 17 over wavelength.

    dF/dlambda = pi^2 D^2 / lambda^2 n_ph,lambda QE(lambda), with n_ph,lambda from eq. 12. With
    ``response`` = 1 over a wide enough grid this reproduces eq. 19; with a passband x QE curve it
    gives the bound of a non-ideal sensor that counts only the photons it detects.

    Parameters
    ----------
    dilution, temperature_k : array (N,)
    wavelength_m : array (L,)
        Integration grid, m.
    response : array (L,) or None
        Fraction of photons detected at each wavelength (QE x transmission), 0..1.

    Returns
    -------
    array (N,), rad^-2
    """
    check_aperture(diameter_m, exposure_s)
    lam = np.asarray(wavelength_m, dtype=float)
    n = photons_per_wavelength(dilution, temperature_k, lam, diameter_m, exposure_s)
    q = 1.0 if response is None else np.asarray(response, dtype=float)
    return np.trapezoid(np.pi**2 * diameter_m**2 / lam**2 * n * q, lam, axis=-1)


def centroid_fisher_spectrum(wavelength_m, irradiance, diameter_m: float, exposure_s: float):
    """Centroid Fisher information of a star with a measured spectrum (eq. 17; Table 1, last row).

    Parameters
    ----------
    wavelength_m : array (L,)
    irradiance : array (L,)
        Spectral irradiance at the sensor, W m^-2 m^-1.
    """
    check_aperture(diameter_m, exposure_s)
    lam = np.asarray(wavelength_m, dtype=float)
    photons = np.asarray(irradiance) * lam / (PLANCK_J_S * SPEED_OF_LIGHT_M_S)
    n = photons * np.pi * diameter_m**2 / 4.0 * exposure_s
    return float(np.trapezoid(np.pi**2 * diameter_m**2 / lam**2 * n, lam))


# ---------------------------------------------------------------------------------------------
# attitude Fisher matrix and covariance


def boresight_frame(target) -> np.ndarray:
    """Rows: unit east, north and boresight of a sensor pointed at ``target`` (ICRS unit vector).

    Used to express a pointed sensor's covariance as two cross-boresight axes and roll; the
    east/north convention is :func:`starsense.geometry.attitude.east_north`'s.
    """
    z = np.asarray(target, dtype=float)
    z = z / np.linalg.norm(z)
    ra, dec = vectors_to_radec(z)
    east, north = east_north(ra, dec)
    return np.stack([east, north, z])


# ---------------------------------------------------------------------------------------------
# stars


@dataclass(frozen=True, eq=False)
class BlackBodyStars:
    """Catalogue stars reduced to what the limit needs.

    Attributes
    ----------
    vectors : array (N, 3)
        ICRS unit vectors.
    temperature_k, dilution : array (N,)
        Equivalent black body of each star (eqs. 1, 9).
    magnitude : array (N,)
        The catalogue magnitude that ranks the stars (N brightest).
    colour : str
        The colour system the black bodies were fitted in.
    n_skipped : int
        Catalogue stars left out for lack of a finite magnitude or colour.
    """

    vectors: np.ndarray = field(repr=False)
    temperature_k: np.ndarray = field(repr=False)
    dilution: np.ndarray = field(repr=False)
    magnitude: np.ndarray = field(repr=False)
    colour: str = "B-V"
    n_skipped: int = 0

    def __len__(self) -> int:
        return len(self.dilution)

    @property
    def fisher_unit(self) -> np.ndarray:
        """F_i for D = 1 m, t = 1 s; scale by D^4 t for any other sensor (eq. 19)."""
        return FISHER_CONSTANT * self.dilution * self.temperature_k**5

    def subset(self, index) -> BlackBodyStars:
        return BlackBodyStars(
            self.vectors[index],
            self.temperature_k[index],
            self.dilution[index],
            self.magnitude[index],
            self.colour,
            self.n_skipped,
        )

    @classmethod
    def from_catalog(cls, catalog, colour: str | None = None) -> BlackBodyStars:
        """Fit every star of a :class:`~starsense.catalog.Catalog` with a black body.

        ``colour`` picks the colour system (default: the first of B-V, BT-VT, J-H, H-Ks, J-Ks,
        V-I, BP-RP that the catalogue has). A catalogue with a magnitude but no colour (BSC5)
        uses B-V from the spectral type (:func:`b_v_from_spectral_type`) when it has one.
        Stars without a finite magnitude or colour are skipped and counted in ``n_skipped``.
        """
        mags, colours = dict(catalog.mags), dict(catalog.colours)
        if "B-V" not in colours and "spectral_type" in getattr(catalog, "extra", {}):
            colours["B-V"] = b_v_from_spectral_type(catalog.extra["spectral_type"])
        available = [c for c in COLOUR_SYSTEMS if c in colours and COLOUR_SYSTEMS[c][2] in mags]
        if colour is None:
            order = ["B-V", "BT-VT", "J-H", "H-Ks", "J-Ks", "V-I", "BP-RP"]
            colour = next((c for c in order if c in available), None)
            if colour is None:
                raise InputError(
                    f"catalogue {catalog.name!r} has no colour index usable for the black-body "
                    f"model (has colours {sorted(colours)} and magnitudes {sorted(mags)})"
                )
        elif colour not in available:
            raise InputError(
                f"catalogue {catalog.name!r} cannot provide colour system {colour!r}; "
                f"available: {', '.join(available) or 'none'}"
            )
        model = ColourModel(colour)
        mag = np.asarray(mags[model.magnitude_band], dtype=float)
        ci = np.asarray(colours[colour], dtype=float)
        ok = np.isfinite(mag) & np.isfinite(ci)
        t, c = model.fit(mag[ok], ci[ok])
        return cls(
            vectors=np.asarray(catalog.vectors)[ok],
            temperature_k=t,
            dilution=c,
            magnitude=mag[ok],
            colour=colour,
            n_skipped=int((~ok).sum()),
        )


# Intrinsic B-V of main-sequence stars by spectral class (Schmidt-Kaler 1982, in Landolt-
# Boernstein VI/2b, as tabulated in Allen's Astrophysical Quantities, 4th ed., Table 15.7).
# Luminosity class and reddening are ignored: a rough colour for catalogues (BSC5) that give only
# a two-character spectral type.
_SPECTRAL_B_V = {
    "O": [(5, -0.33), (9, -0.31)],
    "B": [(0, -0.30), (2, -0.24), (5, -0.17), (8, -0.11)],
    "A": [(0, -0.02), (2, 0.05), (5, 0.15), (7, 0.20)],
    "F": [(0, 0.30), (2, 0.35), (5, 0.44), (8, 0.52)],
    "G": [(0, 0.58), (2, 0.63), (5, 0.68), (8, 0.74)],
    "K": [(0, 0.81), (2, 0.91), (5, 1.15), (7, 1.33)],
    "M": [(0, 1.40), (2, 1.49), (5, 1.64), (8, 1.80)],
}


def b_v_from_spectral_type(types) -> np.ndarray:
    """Approximate B-V from spectral types such as "A0", "K5", "B" (NaN when unknown)."""
    out = np.full(len(types), np.nan)
    for i, s in enumerate(types):
        s = str(s).strip().upper()
        if not s or s[0] not in _SPECTRAL_B_V:
            continue
        table = _SPECTRAL_B_V[s[0]]
        sub = int(s[1]) if len(s) > 1 and s[1].isdigit() else 5
        xs = [p[0] for p in table]
        ys = [p[1] for p in table]
        out[i] = np.interp(sub, xs, ys)
    return out


# ---------------------------------------------------------------------------------------------
# results


@dataclass(frozen=True)
class LimitResult:
    """The attitude-accuracy limit of one sensor (or of merged heads).

    Attributes
    ----------
    theta_rms_rad : float
        sqrt(tr P), eq. 22.
    axis_sigma_rad : array (3,)
        sqrt(diag P) in ``frame``: ICRS x, y, z for the whole sky; for a pointed sensor the two
        cross-boresight axes (east, north) and the roll about the boresight.
    covariance : array (3, 3)
        P in ICRS, rad^2.
    n_stars : int
        Stars contributing.
    g_rad_m2_s05 : float
        G = theta_rms D^2 t^1/2 (eq. 23).
    frame : str
        "icrs" or "boresight".
    """

    theta_rms_rad: float
    axis_sigma_rad: np.ndarray
    covariance: np.ndarray
    n_stars: int
    g_rad_m2_s05: float
    frame: str = "icrs"

    def to_dict(self) -> dict:
        return {
            "theta_rms_rad": self.theta_rms_rad,
            "axis_sigma_rad": [float(x) for x in self.axis_sigma_rad],
            "n_stars": self.n_stars,
            "g_rad_m2_s05": self.g_rad_m2_s05,
            "frame": self.frame,
        }


def limit_from_fisher(fisher, n_stars, diameter_m, exposure_s, frame_rows=None) -> LimitResult:
    """The :class:`LimitResult` of an attitude Fisher matrix (eqs. 20-23).

    The last step of every limit, shared by the in-memory and the distributed paths
    (:mod:`starsense.scale`): ``fisher`` may be a sum of per-chunk matrices.

    Parameters
    ----------
    fisher : array (3, 3)
        Attitude Fisher matrix, rad^-2.
    n_stars : int
        Stars that contributed.
    diameter_m, exposure_s : float
        D (m) and t (s), for G = theta_rms D^2 t^1/2.
    frame_rows : array (3, 3) or None
        Rows of a pointed sensor's frame (:func:`boresight_frame`); None for ICRS axes.
    """
    p = covariance(fisher, n_stars)
    th = theta_rms(p)
    if frame_rows is None:
        axes, frame = np.sqrt(np.diag(p)), "icrs"
    else:
        axes, frame = np.sqrt(np.diag(frame_rows @ p @ frame_rows.T)), "boresight"
    return LimitResult(th, axes, p, n_stars, th * diameter_m**2 * np.sqrt(exposure_s), frame)


def in_cone(vectors, target, fov_diameter_rad: float) -> np.ndarray:
    """Mask of stars inside a cone of full angle ``fov_diameter_rad`` around ``target``."""
    if not (0 < fov_diameter_rad <= 2 * np.pi):
        raise InputError(
            f"FOV diameter must be in (0, 360] deg, got {np.degrees(fov_diameter_rad):.6g} deg"
        )
    t = np.asarray(target, dtype=float)
    t = t / np.linalg.norm(t)
    return np.asarray(vectors) @ t >= np.cos(fov_diameter_rad / 2.0) - 1e-15


def sky_limit(
    stars: BlackBodyStars,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
) -> LimitResult:
    """Limit of the ideal spherical sensor that sees the whole sky (eqs. 19-24)."""
    check_aperture(diameter_m, exposure_s)
    return limit_from_fisher(
        sky_fisher(stars, diameter_m, exposure_s), len(stars), diameter_m, exposure_s
    )


# Per-chunk kernels: each takes any subset of the stars and returns quantities that add exactly
# over disjoint subsets (sums of eq. 21's terms), so the whole-catalogue result is the sum over
# chunks. The in-memory functions call them once on all stars; starsense.scale calls them on
# every partition of a HATS catalogue and adds the results.


def star_weights(stars: BlackBodyStars, diameter_m: float, exposure_s: float) -> np.ndarray:
    """Per-star centroid Fisher information F_i = F_i(1 m, 1 s) D^4 t (eq. 19), rad^-2, (N,)."""
    return stars.fisher_unit * diameter_m**4 * exposure_s


def sky_fisher(stars: BlackBodyStars, diameter_m: float, exposure_s: float) -> np.ndarray:
    """Per-chunk kernel of :func:`sky_limit`: eq. 21 over these stars, (3, 3) rad^-2."""
    return fisher_matrix(stars.vectors, star_weights(stars, diameter_m, exposure_s))


def fov_fishers(
    stars: BlackBodyStars,
    targets,
    fov_diameter_rad: float,
    diameter_m: float,
    exposure_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-chunk kernel of :func:`fov_limit`: each head's Fisher matrix and star count.

    Parameters
    ----------
    targets : array (T, 3)
        Head boresights, ICRS unit vectors.

    Returns
    -------
    fishers : array (T, 3, 3), rad^-2
    counts : array (T,) of int
    """
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    w = star_weights(stars, diameter_m, exposure_s)
    fishers = np.zeros((len(targets), 3, 3))
    counts = np.zeros(len(targets), dtype=np.int64)
    for k, t in enumerate(targets):
        m = in_cone(stars.vectors, t, fov_diameter_rad)
        fishers[k] = fisher_matrix(stars.vectors[m], w[m])
        counts[k] = int(m.sum())
    return fishers, counts


def fov_results(
    fishers, counts, targets, diameter_m: float, exposure_s: float
) -> tuple[list[LimitResult], LimitResult | None]:
    """Heads and merged heads from the summed output of :func:`fov_fishers` (sec. 3.4)."""
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    heads = [
        limit_from_fisher(f, int(n), diameter_m, exposure_s, boresight_frame(t))
        for f, n, t in zip(fishers, counts, targets, strict=True)
    ]
    merged = None
    if len(targets) > 1:
        merged = limit_from_fisher(
            np.sum(fishers, axis=0), int(np.sum(counts)), diameter_m, exposure_s
        )
    return heads, merged


def fov_limit(
    stars: BlackBodyStars,
    targets,
    fov_diameter_rad: float,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
) -> tuple[list[LimitResult], LimitResult | None]:
    """FOV-limited limit (sec. 3.4, Table 2): one head per target, and all heads merged.

    Each head sees the stars in a cone of full angle ``fov_diameter_rad`` around its target
    (unit vector). The merged estimate adds the heads' Fisher matrices: measurements of separate
    heads are independent, so a merged pair is never worse than either head.

    Returns
    -------
    heads : list of LimitResult (axes in each head's boresight frame)
    merged : LimitResult (ICRS axes) or None for a single target
    """
    check_aperture(diameter_m, exposure_s)
    fishers, counts = fov_fishers(stars, targets, fov_diameter_rad, diameter_m, exposure_s)
    return fov_results(fishers, counts, targets, diameter_m, exposure_s)


@dataclass(frozen=True)
class BrightestCurve:
    """theta_rms over the N brightest stars (Fig. 7) and its power-law extrapolation.

    Attributes
    ----------
    n_stars : array (K,)
    theta_rms_rad : array (K,)
        For the given D and t (G itself when D = 1 m, t = 1 s).
    slope : float
        d log theta / d log N fitted over the last decade of the catalogue.
    n_extrapolated : float
        N the curve is extrapolated to (paper: 3e11 stars in the Galaxy).
    theta_extrapolated_rad : float
    colour : str
    """

    n_stars: np.ndarray
    theta_rms_rad: np.ndarray
    slope: float
    intercept: float
    n_extrapolated: float
    theta_extrapolated_rad: float
    colour: str

    def extrapolate(self, n) -> np.ndarray:
        return 10 ** (self.intercept + self.slope * np.log10(n))

    def to_dict(self) -> dict:
        return {
            "colour": self.colour,
            "n_stars": [int(n) for n in self.n_stars],
            "theta_rms_rad": [float(x) for x in self.theta_rms_rad],
            "slope": self.slope,
            "n_extrapolated": self.n_extrapolated,
            "theta_extrapolated_rad": self.theta_extrapolated_rad,
        }


def brightest_curve(
    stars: BlackBodyStars,
    diameter_m: float = 1.0,
    exposure_s: float = 1.0,
    points_per_decade: int = 20,
    n_extrapolated: float = N_GALAXY,
) -> BrightestCurve:
    """theta_rms of the N brightest stars, N = 2 ... all (Fig. 7), in one pass over the stars.

    Stars are ranked by catalogue magnitude (ties broken by position, :func:`brightest_order`);
    the six independent components of sum w r r^T and
    sum w are accumulated between checkpoints with ``np.add.reduceat``. N with a singular
    geometry (e.g. N = 2 antipodal stars) is dropped from the curve.
    """
    check_aperture(diameter_m, exposure_s)
    n_total = len(stars)
    if n_total < 2:
        raise SingularGeometryError(f"singular geometry ({n_total} star): need at least 2 stars")
    w = star_weights(stars, diameter_m, exposure_s)
    order = brightest_order(stars.magnitude, stars.vectors, w)
    comps = fisher_components(stars.vectors[order], w[order])
    ns = brightest_checkpoints(n_total, points_per_decade)
    starts = np.concatenate([[0], ns[:-1]])
    sums = np.cumsum(np.add.reduceat(comps, starts, axis=0), axis=0)
    return brightest_from_sums(ns, sums, n_extrapolated, stars.colour)


# Kernels of the N-brightest curve, shared with the distributed path (starsense.scale).


def brightest_order(magnitude, vectors, weights) -> np.ndarray:
    """Indices that rank stars brightest first, independent of their order in the catalogue.

    Stars are sorted by magnitude; stars of equal magnitude (common in catalogues that round to
    0.01 mag) by x, y, z of the unit vector and then the weight, so that any partitioning of a
    catalogue (HATS tiles) ranks them the same way and the N-brightest sums agree exactly.
    """
    mag = np.asarray(magnitude, dtype=float)
    order = np.argsort(mag, kind="stable")
    ms = mag[order]
    tie = ms[1:] == ms[:-1]
    if tie.any():
        in_group = np.zeros(len(ms), dtype=bool)
        in_group[1:] |= tie
        in_group[:-1] |= tie
        pos = np.flatnonzero(in_group)  # runs of equal magnitude, contiguous and ascending
        o = order[pos]
        r = np.asarray(vectors, dtype=float)[o]
        w = np.asarray(weights, dtype=float)[o]
        order[pos] = o[np.lexsort((w, r[:, 2], r[:, 1], r[:, 0], mag[o]))]
    return order


def fisher_components(vectors, weights) -> np.ndarray:
    """The seven independent terms of eq. 21 per star: w, w x^2, w y^2, w z^2, w xy, w xz, w yz.

    Returns
    -------
    array (N, 7)
        Any sum of rows is the (sum w, sum w r r^T) of those stars; see
        :func:`fisher_from_components`.
    """
    r = np.asarray(vectors, dtype=float)
    w = np.asarray(weights, dtype=float)
    return np.column_stack(
        [
            w,
            w * r[:, 0] ** 2,
            w * r[:, 1] ** 2,
            w * r[:, 2] ** 2,
            w * r[:, 0] * r[:, 1],
            w * r[:, 0] * r[:, 2],
            w * r[:, 1] * r[:, 2],
        ]
    )


def fisher_from_components(sums) -> np.ndarray:
    """Eq. 21's F = sum w I - sum w r r^T from a row of summed :func:`fisher_components`."""
    sw, xx, yy, zz, xy, xz, yz = np.asarray(sums, dtype=float)
    return sw * np.eye(3) - np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def brightest_checkpoints(n_total: int, points_per_decade: int = 20) -> np.ndarray:
    """N at which the curve is evaluated: log-spaced from 2 to ``n_total``, which is included."""
    return np.unique(
        np.concatenate(
            [
                np.round(
                    np.logspace(
                        np.log10(2),
                        np.log10(n_total),
                        1 + int(points_per_decade * np.log10(n_total / 2)),
                    )
                ).astype(int),
                [n_total],
            ]
        )
    )


def brightest_from_sums(
    ns, sums, n_extrapolated: float = N_GALAXY, colour: str = ""
) -> BrightestCurve:
    """The curve from the summed components of the ``ns[k]`` brightest stars, ``sums[k]``.

    theta_rms at each N (eq. 22), dropping N with a singular geometry, and the power-law fit
    over the last decade extrapolated to ``n_extrapolated`` stars.
    """
    keep_n, theta = [], []
    for n, s in zip(ns, sums, strict=True):
        try:
            theta.append(theta_rms(covariance(fisher_from_components(s), int(n))))
            keep_n.append(n)
        except SingularGeometryError:
            continue
    ns_arr, th_arr = np.array(keep_n), np.array(theta)
    tail = ns_arr >= max(ns_arr[-1] / 10.0, 2)
    if tail.sum() < 2:
        tail = np.ones_like(ns_arr, dtype=bool)
    slope, intercept = np.polyfit(np.log10(ns_arr[tail]), np.log10(th_arr[tail]), 1)
    extrap = float(10 ** (intercept + slope * np.log10(n_extrapolated)))
    return BrightestCurve(
        ns_arr,
        th_arr,
        float(slope),
        float(intercept),
        float(n_extrapolated),
        extrap,
        colour,
    )


@dataclass(frozen=True)
class LowPhotonResult:
    """Sec. 3.3.2: what a small sensor or short exposure loses to stars delivering few photons.

    Attributes
    ----------
    expected_photons : array (N,)
        iota_i, the Poisson mean of photons from each star.
    n_below_one_photon : int
        Stars expected to deliver fewer than one photon.
    expected_observed_stars : float
        sum_i (1 - exp(-iota_i)): the mean number of stars with at least one photon.
    theta_ideal_rad : float
        The bound with every star's expected photons (eq. 22).
    theta_poisson_rad : float
        rms attitude bound over Monte Carlo draws of the photon counts N_i ~ Poisson(iota_i),
        F_i scaled by N_i / iota_i (information carried by the photons actually detected).
    degradation : float
        theta_poisson / theta_ideal (>= 1 in expectation: Jensen's inequality on tr F^-1).
    n_trials : int
    """

    expected_photons: np.ndarray
    n_below_one_photon: int
    expected_observed_stars: float
    theta_ideal_rad: float
    theta_poisson_rad: float
    degradation: float
    n_trials: int

    def to_dict(self) -> dict:
        return {
            "n_stars": len(self.expected_photons),
            "n_below_one_photon": self.n_below_one_photon,
            "expected_observed_stars": self.expected_observed_stars,
            "theta_ideal_rad": self.theta_ideal_rad,
            "theta_poisson_rad": self.theta_poisson_rad,
            "degradation": self.degradation,
            "n_trials": self.n_trials,
        }


def low_photon_degradation(
    stars: BlackBodyStars,
    diameter_m: float,
    exposure_s: float,
    n_trials: int = 200,
    rng: np.random.Generator | int | None = 0,
) -> LowPhotonResult:
    """Low-photon degradation of the limit (Fialho & Mortari 2019, sec. 3.3.2).

    Stars whose expected photon count is large (> 1e4) are treated as deterministic: their
    relative Poisson fluctuation is below 1 %, and drawing them would only cost time.
    Trials with a singular geometry (too few stars seen) count as infinite error and make the
    result infinite: the sensor cannot solve in those exposures.
    """
    check_aperture(diameter_m, exposure_s)
    if n_trials < 1:
        raise InputError(f"n_trials must be >= 1, got {n_trials}")
    rng = np.random.default_rng(rng)
    iota = total_photons(stars.dilution, stars.temperature_k, diameter_m, exposure_s)
    w = stars.fisher_unit * diameter_m**4 * exposure_s
    r = stars.vectors
    ideal = theta_rms(covariance(fisher_matrix(r, w), len(stars)))
    fixed = iota > 1e4
    f_fixed = fisher_matrix(r[fixed], w[fixed])
    rv, wv, iv = r[~fixed], w[~fixed], iota[~fixed]
    comps = (
        np.column_stack(
            [
                wv / iv * (1 - rv[:, i] * rv[:, j]) if i == j else -wv / iv * rv[:, i] * rv[:, j]
                for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
            ]
        )
        if len(iv)
        else np.zeros((0, 6))
    )
    sq = []
    chunk = max(1, int(2e7 // max(len(iv), 1)))
    for start in range(0, n_trials, chunk):
        k = min(chunk, n_trials - start)
        counts = rng.poisson(iv, size=(k, len(iv))).astype(float)
        s = counts @ comps  # (k, 6)
        for row in s:
            f = f_fixed + np.array(
                [[row[0], row[3], row[4]], [row[3], row[1], row[5]], [row[4], row[5], row[2]]]
            )
            try:
                sq.append(np.trace(covariance(f)))
            except SingularGeometryError:
                sq.append(np.inf)
    poisson = float(np.sqrt(np.mean(sq)))
    return LowPhotonResult(
        expected_photons=iota,
        n_below_one_photon=int((iota < 1).sum()),
        expected_observed_stars=float(np.sum(-np.expm1(-iota))),
        theta_ideal_rad=ideal,
        theta_poisson_rad=poisson,
        degradation=poisson / ideal,
        n_trials=n_trials,
    )


def limit_line(g_rad_m2_s05, d2_sqrt_t):
    """Theta = G / (D^2 t^1/2) (eq. 23) as a function of the figure of merit D^2 t^1/2."""
    return np.asarray(g_rad_m2_s05) / np.asarray(d2_sqrt_t)
