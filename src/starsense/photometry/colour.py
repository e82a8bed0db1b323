"""Colour index -> black-body temperature, magnitude -> dilution factor C.

Fialho & Mortari 2019, sec. 2.5-2.6: the synthetic colour index of a black body is computed on a
grid of temperatures, then inverted by pchip interpolation of 1/T against the colour (nearly linear,
Fig. 5), with the colour clamped to the values of 30,000 K and 2,000 K. The dilution factor follows
from the black body's magnitude at its own surface (eq. 9).

A :class:`ColourModel` is one colour system (a pair of bands) plus the band whose magnitude sets C.
The paper's systems, the curves of its Fig. 7, are in :data:`COLOUR_SYSTEMS`.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from starsense.errors import InputError
from starsense.photometry.blackbody import spectral_exitance
from starsense.photometry.passbands import passband

#: colour name -> (blue band, red band, band whose magnitude sets the dilution C)
COLOUR_SYSTEMS: dict[str, tuple[str, str, str]] = {
    "B-V": ("B", "V", "V"),  # paper sec. 2.5-2.6, Hipparcos
    "V-I": ("V", "I", "V"),  # Hipparcos V-I curve of Fig. 7
    "BT-VT": ("BT", "VT", "VT"),  # Tycho-2
    "J-H": ("J", "H", "J"),  # 2MASS, sec. 3.4 ("from the J and H magnitudes")
    "J-Ks": ("J", "Ks", "J"),
    "H-Ks": ("H", "Ks", "H"),  # Table 1 lower half: m_H with H-Ks
    "BP-RP": ("BP", "RP", "G"),  # Gaia: temperature from BP-RP, C from G
}

#: paper's temperature clamp, K (sec. 2.5)
T_MIN_K = 2000.0
T_MAX_K = 30000.0

# grid over which the synthetic colour is tabulated: wider than the clamp so that pchip is
# well-behaved at its ends; 1/T is the interpolation variable.
_T_GRID_K = np.geomspace(1000.0, 200000.0, 1200)
# points of the dense lookup tables (uniform grids, see _uniform_interp)
_DENSE = 20001


def _uniform_interp(x, x0: float, x1: float, table: np.ndarray) -> np.ndarray:
    """Linear interpolation in ``table`` sampled uniformly on [x0, x1], clamped at the ends.

    Same result as ``np.interp`` on a uniform grid, without its per-element binary search:
    O(1) per point, which matters over millions of stars.
    """
    n = table.size - 1
    # clamped first: a colour of 1e308 would overflow the scaling (NaN stays NaN)
    x = np.clip(np.asarray(x, dtype=float), min(x0, x1), max(x0, x1))
    u = (x - x0) * (n / (x1 - x0))
    u = np.clip(u, 0.0, n)  # NaN stays NaN
    i = np.minimum(np.nan_to_num(u, nan=0.0).astype(np.intp), n - 1)
    f = u - i
    return table[i] * (1.0 - f) + table[i + 1] * f


@functools.cache
def _surface_magnitudes(band: str) -> np.ndarray:
    """Magnitude of a black body seen from its own surface, over _T_GRID_K (Fig. 4)."""
    pb = passband(band)
    # chunk over temperatures to bound memory (grid of up to ~15,000 wavelengths)
    out = np.empty(_T_GRID_K.size)
    for i in range(0, _T_GRID_K.size, 200):
        t = _T_GRID_K[i : i + 200]
        out[i : i + 200] = pb.magnitude(None, spectral_exitance(t, pb.wavelength_m))
    return out


@dataclass(frozen=True)
class ColourModel:
    """Black-body fit of a star from one colour index and one magnitude.

    Parameters
    ----------
    colour : str
        A key of :data:`COLOUR_SYSTEMS` ("B-V", "V-I", "BT-VT", "J-H", "J-Ks", "H-Ks", "BP-RP").
    t_min_k, t_max_k : float
        Temperature clamp, K (paper: 2000 and 30,000 K).
    """

    colour: str = "B-V"
    t_min_k: float = T_MIN_K
    t_max_k: float = T_MAX_K

    def __post_init__(self) -> None:
        if self.colour not in COLOUR_SYSTEMS:
            raise InputError(
                f"unknown colour system {self.colour!r}; known: {', '.join(COLOUR_SYSTEMS)}"
            )
        if not (_T_GRID_K[0] <= self.t_min_k < self.t_max_k <= _T_GRID_K[-1]):
            raise InputError(
                f"temperature clamp [{self.t_min_k}, {self.t_max_k}] K must satisfy "
                f"{_T_GRID_K[0]:.0f} <= t_min_k < t_max_k <= {_T_GRID_K[-1]:.0f}"
            )

    @property
    def blue_band(self) -> str:
        """Band of the colour index's bluer magnitude (B for B-V)."""
        return COLOUR_SYSTEMS[self.colour][0]

    @property
    def red_band(self) -> str:
        """Band of the colour index's redder magnitude (V for B-V)."""
        return COLOUR_SYSTEMS[self.colour][1]

    @property
    def magnitude_band(self) -> str:
        """The band whose catalogue magnitude sets the dilution factor C (eq. 9)."""
        return COLOUR_SYSTEMS[self.colour][2]

    @functools.cached_property
    def _tables(self):
        from scipy.interpolate import PchipInterpolator

        blue = _surface_magnitudes(self.blue_band)
        red = _surface_magnitudes(self.red_band)
        ci = blue - red  # decreasing with T
        inv_t = 1.0 / _T_GRID_K
        # ascending in colour <=> ascending in 1/T
        ci_asc, inv_asc = ci[::-1], inv_t[::-1]
        if np.any(np.diff(ci_asc) <= 0):
            raise RuntimeError(f"synthetic {self.colour} is not monotonic in temperature")
        to_inv_t = PchipInterpolator(ci_asc, inv_asc)
        mag_surface = PchipInterpolator(inv_asc, _surface_magnitudes(self.magnitude_band)[::-1])
        colour_of_inv_t = PchipInterpolator(inv_asc, ci_asc)
        lo = float(colour_of_inv_t(1.0 / self.t_max_k))
        hi = float(colour_of_inv_t(1.0 / self.t_min_k))
        # The pchip curves sampled on dense grids, evaluated by direct indexing: over millions
        # of stars this is ~10x faster than evaluating the pchip, and the linear interpolation error
        # (spacing^2 / 8 x curvature) is ~2e-8 in T and ~6e-8 mag (tested against the pchip).
        dense_ci = np.linspace(lo, hi, _DENSE)
        dense_inv_t = np.linspace(1.0 / self.t_max_k, 1.0 / self.t_min_k, _DENSE)
        return {
            "to_inv_t": to_inv_t,
            "mag_surface": mag_surface,
            "colour_of_inv_t": colour_of_inv_t,
            "limits": (lo, hi),
            "dense_ci": dense_ci,
            "dense_inv_t_of_ci": to_inv_t(dense_ci),
            "dense_inv_t": dense_inv_t,
            "dense_mag_surface": mag_surface(dense_inv_t),
        }

    @property
    def colour_limits(self) -> tuple[float, float]:
        """Colour indices of the clamp temperatures (t_max_k, t_min_k).

        The paper's [-0.2357, +2.7028] for B-V.
        """
        return self._tables["limits"]

    def colour_index(self, temperature_k) -> np.ndarray:
        """Synthetic colour index of a black body at ``temperature_k`` (Fig. 5)."""
        return self._tables["colour_of_inv_t"](1.0 / np.asarray(temperature_k, dtype=float))

    def surface_magnitude(self, temperature_k) -> np.ndarray:
        """m_BB,surface(T) in the magnitude band (Fig. 4); T within the clamp."""
        tab = self._tables
        inv_t = 1.0 / np.asarray(temperature_k, dtype=float)
        out = _uniform_interp(
            inv_t, tab["dense_inv_t"][0], tab["dense_inv_t"][-1], tab["dense_mag_surface"]
        )
        # outside the clamp (callers passing their own T): the pchip, for those stars only;
        # a relative margin keeps clamped temperatures (rounded at the ends) on the fast path
        lo, hi = tab["dense_inv_t"][0], tab["dense_inv_t"][-1]
        outside = (inv_t < lo * (1 - 1e-12)) | (inv_t > hi * (1 + 1e-12))
        if np.any(outside):
            out = np.array(out, dtype=float, copy=True)
            out[outside] = tab["mag_surface"](inv_t[outside])
        return out

    def temperature_k(self, colour_index) -> np.ndarray:
        """Black-body temperature for a colour index, clamped to [t_min_k, t_max_k] (sec. 2.5).

        NaN colours give NaN temperatures: callers decide whether that is an error (one star) or a
        star to skip (a catalogue).
        """
        tab = self._tables
        ci = np.asarray(colour_index, dtype=float)
        # clamping to the table's ends is exactly the paper's colour clamp
        lo, hi = tab["limits"]
        return 1.0 / _uniform_interp(ci, lo, hi, tab["dense_inv_t_of_ci"])

    def dilution(self, magnitude, temperature_k) -> np.ndarray:
        """Geometric dilution factor C = 10^(0.4 (m_BB,surface(T) - m)), eq. 9."""
        return 10.0 ** (0.4 * (self.surface_magnitude(temperature_k) - np.asarray(magnitude)))

    def fit(self, magnitude, colour_index) -> tuple[np.ndarray, np.ndarray]:
        """Temperature (K) and dilution C of the equivalent black body of each star."""
        t = self.temperature_k(colour_index)
        return t, self.dilution(magnitude, t)


def fit_star(magnitude: float, colour_index: float, colour: str = "B-V") -> tuple[float, float]:
    """Black-body (T, C) of one star, with a specific error for non-finite input."""
    for name, value in (("magnitude", magnitude), ("colour index", colour_index)):
        if not np.isfinite(value):
            raise InputError(f"{name} must be a finite number, got {value!r}")
    t, c = ColourModel(colour).fit(magnitude, colour_index)
    return float(t), float(c)


# -- Gaia G, BP-RP -> Johnson V, B-V -------------------------------------------------------------

#: G - V against BP - RP for Gaia (E)DR3 photometry: Riello et al. 2021, A&A 649, A3,
#: Table C.2 (rms 0.0277 mag; valid -0.5 < BP-RP < 5.0), coefficients of 1, c, c^2, c^3
RIELLO2021_G_MINUS_V = (-0.02704, 0.01424, -0.2156, 0.01426)
RIELLO2021_BP_RP_RANGE = (-0.5, 5.0)
#: G - V against Johnson B - V: Evans et al. 2018, A&A 616, A4, Table C.2 (rms 0.06285 mag),
#: coefficients of 1, x, x^2, x^3; and G - V against BP - RP from the same table (rms 0.045858
#: mag, valid -0.5 < BP-RP < 2.75): B - V is the first inverted at the second's G - V
EVANS2018_G_MINUS_V_BV = (-0.02907, -0.02385, -0.2297, -0.001768)
EVANS2018_G_MINUS_V_BP_RP = (-0.01760, -0.006860, -0.1732)
#: the colour assumed for a star without BP - RP: the median BP - RP of Gaia stars to G = 10
#: is about 1.0 (F-G dwarfs and K giants); V is then G + 0.21, uncertain by ~0.3 mag
DEFAULT_BP_RP = 1.0


def gaia_to_johnson(g, bp_rp):
    """Return Johnson V and B - V from Gaia G and BP - RP (published photometric relations).

    V = G - (G - V)(BP - RP) with Riello et al. 2021, Table C.2 (Gaia EDR3/DR3; rms 0.03 mag).
    B - V solves Evans et al. 2018, Table C.2 (G - V as a cubic in B - V) for the G - V that
    the same table gives from BP - RP, on the cubic's monotonic branch B - V in [-0.05, 2.5]
    (rms ~0.1 mag; stars bluer than BP - RP ~ 0.1 get -0.05). Colours outside Riello's range
    -0.5 ... 5 are clipped to it; a missing BP - RP (NaN) takes :data:`DEFAULT_BP_RP`.

    Parameters
    ----------
    g : array_like (N,)
        Gaia G, mag.
    bp_rp : array_like (N,)
        Gaia BP - RP, mag (NaN: unknown).

    Returns
    -------
    v, b_v : ndarray (N,)
        Johnson V and B - V, mag.
    """
    g = np.asarray(g, dtype=float)
    c = np.asarray(bp_rp, dtype=float)
    c = np.clip(np.where(np.isfinite(c), c, DEFAULT_BP_RP), *RIELLO2021_BP_RP_RANGE)
    g_minus_v = np.polynomial.polynomial.polyval(c, RIELLO2021_G_MINUS_V)
    gv_evans = np.polynomial.polynomial.polyval(np.minimum(c, 2.75), EVANS2018_G_MINUS_V_BP_RP)
    # Evans's cubic decreases monotonically on [-0.05, 2.5]: invert it on a fine table
    bv_grid = np.linspace(-0.05, 2.5, 2551)
    gv_grid = np.polynomial.polynomial.polyval(bv_grid, EVANS2018_G_MINUS_V_BV)
    b_v = np.interp(-gv_evans, -gv_grid, bv_grid)  # np.interp needs increasing abscissae
    return g - g_minus_v, b_v


def with_johnson_from_gaia(catalog):
    """Return ``catalog`` with V and B - V from its G and BP - RP, and a note saying how.

    A catalogue that has V already, or no G, is returned as is (note None). Stars without
    BP - RP take :data:`DEFAULT_BP_RP` (the note counts them).

    Parameters
    ----------
    catalog : Catalog
        A Gaia catalogue (band ``G``, colour ``BP-RP`` if known).

    Returns
    -------
    catalog : Catalog
        With ``mags["V"]`` and ``colours["B-V"]`` (:func:`gaia_to_johnson`).
    note : str or None
        What was done, for the warnings of an analysis.
    """
    if "V" in catalog.mags or "G" not in catalog.mags:
        return catalog, None
    g = catalog.mags["G"]
    bp_rp = catalog.colours.get("BP-RP", np.full(len(g), np.nan))
    v, b_v = gaia_to_johnson(g, bp_rp)
    n_missing = int(np.sum(~np.isfinite(bp_rp) & np.isfinite(g)))
    note = (
        f"V and B-V of {catalog.name} from G and BP-RP (Riello et al. 2021, Table C.2: rms 0.03 "
        "mag; Evans et al. 2018, Table C.2)"
    )
    if n_missing:
        note += (
            f"; {n_missing:,} of {len(g):,} stars have no BP-RP and take BP-RP = "
            f"{DEFAULT_BP_RP:g} (V = G + {float(gaia_to_johnson(0.0, DEFAULT_BP_RP)[0]):.2f}, "
            "uncertain by ~0.3 mag)"
        )
    out = dataclasses.replace(
        catalog, mags={**catalog.mags, "V": v}, colours={**catalog.colours, "B-V": b_v}
    )
    return out, note


#: the monotonic branch of Evans et al. 2018's G - V cubic in B - V (:func:`gaia_to_johnson`)
EVANS2018_B_V_RANGE = (-0.05, 2.5)


def magnitudes_in(catalog, band: str) -> np.ndarray:
    """Return each star's magnitude in ``band``: its own, else from the bands it has.

    A catalogue rendered beside another (Hipparcos beside the narrow field's Gaia DR3) lacks
    the other's band for its own stars. A star without ``band`` takes it from published
    relations where its catalogue gives their inputs: Gaia G from Johnson V and B - V (Evans et
    al. 2018, Table C.2: rms 0.06 mag; B - V clipped to the cubic's monotonic branch, a star
    without B - V taking that of :data:`DEFAULT_BP_RP`), Johnson V from G and BP - RP
    (:func:`gaia_to_johnson`: rms 0.03 mag). NaN where neither applies.

    Parameters
    ----------
    catalog : Catalog
    band : str

    Returns
    -------
    ndarray (N,)
        mag.
    """
    n = len(catalog.ids)
    nan = np.full(n, np.nan)
    out = np.array(catalog.mags.get(band, nan), dtype=float)
    miss = ~np.isfinite(out)
    if not miss.any():
        return out
    if band == "G" and "V" in catalog.mags:
        bv = np.asarray(catalog.colours.get("B-V", nan), dtype=float)
        default_bv = float(gaia_to_johnson(0.0, DEFAULT_BP_RP)[1])
        bv = np.clip(np.where(np.isfinite(bv), bv, default_bv), *EVANS2018_B_V_RANGE)
        g = np.asarray(catalog.mags["V"], dtype=float) + np.polynomial.polynomial.polyval(
            bv, EVANS2018_G_MINUS_V_BV
        )
        out[miss] = g[miss]
    elif band == "V" and "G" in catalog.mags:
        v, _ = gaia_to_johnson(catalog.mags["G"], catalog.colours.get("BP-RP", nan))
        out[miss] = v[miss]
    return out
