"""Photometric passbands, Vega's spectrum and magnitude zero points.

Passband curves and Vega's CALSPEC spectrum (``alpha_lyr_stis_011``) come from the PyPI package
``astro-sedpy``, which ships them, so everything works offline. sedpy tabulates each curve as a
*photonic* response S(lambda) (detector signal per photon); the paper integrates energy with the
energy response R(lambda) = lambda S(lambda) (Bessell & Murphy 2012, eq. A9, as Fialho & Mortari
2019 sec. 2.5 do). Curves are resampled with a shape-preserving pchip, as the paper does, onto a
0.1 nm grid, fine enough to resolve the absorption lines of Vega's spectrum: sampling Vega at
the curves' own 10 nm steps shifts B-V by ~0.02 mag and Vega's black-body temperature by ~7 %.

Zero points (Fialho & Mortari 2019, eqs. 7-8):

* Vega-based bands: the reference flux is the band flux of Vega scaled so that Vega has the
  magnitude below. B = 0.029 and V = 0.030 are the paper's (Hipparcos values). I = 0.040 follows
  from Vega's V-I = -0.010 in the Hipparcos new reduction (hip2.dat, HIP 91262), and
  Hp = 0.0868 is Vega's Hp there. U and R take 0.030 (Vega's U-B and V-R are ~0 by the system's
  definition; these bands feed no colour system of the paper). Tycho BT = 0.029 and
  VT = 0.030 follow from the published Tycho-Johnson relations V = VT - 0.090 (BT-VT) and
  B-V = 0.850 (BT-VT) (ESA 1997, SP-1200 vol. 1, sec. 1.3) at Vega's B-V = -0.001.
  Gaia G, BP, RP take 0.030
  (the Gaia VEGAMAG convention; sedpy's revised DR2 passbands, the closest it has to DR3's).
* 2MASS J, H, Ks: the zero-magnitude in-band fluxes of Cohen, Wheaton & Megeath 2003 (AJ 126,
  1090), Table 2, third column, as the paper does: 3.129e-13, 1.133e-13, 4.283e-14 W cm^-2 um^-1.
  The in-band flux of a spectrum is its photon-weighted mean F_lambda, the integral of
  F_lambda lambda S over the integral of lambda S (Cohen et al. 2003, eq. 1).
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, field

import numpy as np

from starsense.errors import InputError

#: wavelength step of the resampled passbands, m (0.1 nm)
GRID_STEP_M = 1e-10

# W cm^-2 um^-1 -> W m^-2 m^-1: 1e4 cm^2/m^2 x 1e6 um/m
_W_CM2_UM_TO_SI = 1e10
# erg s^-1 cm^-2 A^-1 -> W m^-2 m^-1: 1e-7 J/erg x 1e4 cm^2/m^2 x 1e10 A/m
_ERG_S_CM2_A_TO_SI = 1e7

#: band name -> (sedpy filter file, kind, value): kind "vega" (Vega's magnitude) or
#: "flux" (zero-magnitude in-band F_lambda, W m^-2 m^-1)
BANDS: dict[str, tuple[str, str, float]] = {
    "U": ("bessell_U", "vega", 0.030),
    "B": ("bessell_B", "vega", 0.029),
    "V": ("bessell_V", "vega", 0.030),
    "R": ("bessell_R", "vega", 0.030),
    "I": ("bessell_I", "vega", 0.040),
    "Hp": ("hipparcos_H", "vega", 0.0868),
    "BT": ("hipparcos_B", "vega", 0.029),
    "VT": ("hipparcos_V", "vega", 0.030),
    "J": ("twomass_J", "flux", 3.129e-13 * _W_CM2_UM_TO_SI),
    "H": ("twomass_H", "flux", 1.133e-13 * _W_CM2_UM_TO_SI),
    "Ks": ("twomass_Ks", "flux", 4.283e-14 * _W_CM2_UM_TO_SI),
    "G": ("gaia_g_dr2rev", "vega", 0.030),
    "BP": ("gaia_bp_dr2rev", "vega", 0.030),
    "RP": ("gaia_rp_dr2rev", "vega", 0.030),
}


def _sedpy_data_dir() -> str:
    import sedpy

    return os.path.join(os.path.dirname(sedpy.__file__), "data")


@functools.lru_cache(maxsize=1)
def vega_spectrum() -> tuple[np.ndarray, np.ndarray]:
    """Vega's spectral irradiance at the top of the atmosphere (CALSPEC alpha_lyr_stis_011).

    Returns
    -------
    wavelength_m : array (L,)
    irradiance : array (L,)
        W m^-2 m^-1.
    """
    from astropy.io import fits

    path = os.path.join(_sedpy_data_dir(), "alpha_lyr_stis_011.fits")
    with fits.open(path) as hdul:
        data = hdul[1].data
        wavelength_m = np.array(data["WAVELENGTH"], dtype=float) * 1e-10
        irradiance = np.array(data["FLUX"], dtype=float) * _ERG_S_CM2_A_TO_SI
    return wavelength_m, irradiance


@functools.lru_cache(maxsize=1)
def sun_spectrum() -> tuple[np.ndarray, np.ndarray]:
    """Return the Sun's spectral irradiance at 1 au (Kurucz 1993, shipped by sedpy), W m^-2 m^-1.

    Its integral is 1359 W m^-2, the solar constant; the model's far-UV rows below 160 nm are
    NaN in the file and are dropped (they carry a negligible share of the photons).
    """
    from astropy.io import fits

    path = os.path.join(_sedpy_data_dir(), "sun_kurucz93.fits")
    with fits.open(path) as hdul:
        data = hdul[1].data
        wavelength_m = np.array(data["WAVELENGTH"], dtype=float) * 1e-10
        irradiance = np.array(data["FLUX"], dtype=float) * _ERG_S_CM2_A_TO_SI
    ok = np.isfinite(irradiance)
    return wavelength_m[ok], irradiance[ok]


@dataclass(frozen=True, eq=False, kw_only=True)
class Passband:
    """A photometric band resampled on a fine grid, with its zero point.

    Attributes
    ----------
    name : str
        Band name ("V", "Hp", "J", ...).
    wavelength_m : array (L,)
        Grid, m.
    photon_response : array (L,)
        Detector signal per photon, arbitrary normalisation.
    reference_flux : float
        phi_REF of eqs. 7-8: the integral of E(lambda) R(lambda) d lambda (W m^-2 up to R's
        normalisation) of a source of magnitude zero.
    """

    name: str
    wavelength_m: np.ndarray = field(repr=False)
    photon_response: np.ndarray = field(repr=False)
    reference_flux: float

    @property
    def energy_response(self) -> np.ndarray:
        """R(lambda) = lambda S(lambda), shape (L,)."""
        return self.wavelength_m * self.photon_response

    def band_flux(self, wavelength_m, spectral_irradiance) -> np.ndarray:
        """Integral of E(lambda) R(lambda) over the band (eqs. 3-4, 7-8).

        Parameters
        ----------
        wavelength_m : array (L,) or None
            Wavelengths of the spectrum; None means the spectrum is already on this band's grid.
        spectral_irradiance : array (..., L)
            W m^-2 m^-1.
        """
        e = np.asarray(spectral_irradiance, dtype=float)
        if wavelength_m is not None:
            e = np.interp(self.wavelength_m, wavelength_m, e, left=0.0, right=0.0)
        return np.trapezoid(e * self.energy_response, self.wavelength_m, axis=-1)

    def magnitude(self, wavelength_m, spectral_irradiance) -> np.ndarray:
        """Synthetic magnitude of a spectrum in this band (eqs. 5-6)."""
        return -2.5 * np.log10(
            self.band_flux(wavelength_m, spectral_irradiance) / self.reference_flux
        )


def _load_curve(filter_name: str) -> tuple[np.ndarray, np.ndarray]:
    from scipy.interpolate import PchipInterpolator
    from sedpy import observate

    f = observate.Filter(filter_name)
    lam = np.asarray(f.wavelength, dtype=float) * 1e-10
    s = np.asarray(f.transmission, dtype=float)
    order = np.argsort(lam)
    lam, s = lam[order], s[order]
    keep = np.concatenate([[True], np.diff(lam) > 0])
    lam, s = lam[keep], s[keep]
    grid = np.arange(lam[0], lam[-1] + GRID_STEP_M / 2, GRID_STEP_M)
    resp = np.clip(PchipInterpolator(lam, s)(grid), 0.0, None)
    return grid, resp


@functools.cache
def passband(name: str) -> Passband:
    """Return the passband called ``name`` (one of :data:`BANDS`), with its zero point set."""
    if name not in BANDS:
        raise InputError(f"unknown passband {name!r}; known bands: {', '.join(BANDS)}")
    filter_name, kind, value = BANDS[name]
    grid, resp = _load_curve(filter_name)
    energy = grid * resp
    if kind == "vega":
        vl, vf = vega_spectrum()
        vega_flux = np.trapezoid(np.interp(grid, vl, vf) * energy, grid)
        reference = 10 ** (0.4 * value) * vega_flux
    else:
        # zero-magnitude in-band F_lambda times the integral of R: a source with that constant
        # F_lambda across the band has magnitude zero.
        reference = value * np.trapezoid(energy, grid)
    return Passband(name=name, wavelength_m=grid, photon_response=resp, reference_flux=reference)
