"""Sensitivity models: photoelectrons a sensor collects from a star (Dzamba & Enright 2014).

* Liebe (eqs. 3-6): a zero-magnitude 5,800 K black body scaled to 2.96e-14 W mm^-2 in total,
  converted to photons, weighted by the detector QE over its passband; a star of magnitude m gives
  S_e = t_e (pi D^2 / 4) S_0 / 2.5^m. Eq. 6 divides by 2.5^m, as printed (Liebe's tutorial
  rounding of 10^0.4 = 2.512); we keep it to reproduce the paper.
* Reed (eqs. 7-8): phi_0 = 1.8e10 photons m^-2 s^-1 for m = 0, times the mean QE:
  S_e = eta_Q t_e (pi D^2 / 4) phi_0 10^(-0.4 m).
* Black body (colour-aware): each star's own black body (T, C from
  :class:`~starsense.photometry.colour.ColourModel`), photons by Fialho & Mortari eq. 12, weighted
  by the QE curve over the passband.

These are kernels on plain parameters (no sensor object), so the sensor stage and the analyses
share them. ``transmission`` multiplies every model (optical throughput).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from starsense.errors import InputError
from starsense.photometry.blackbody import (
    BOLTZMANN_J_K,
    PLANCK_J_S,
    SPEED_OF_LIGHT_M_S,
    aperture_area_m2,
    photons_per_wavelength,
    spectral_exitance,
)
from starsense.photometry.colour import ColourModel

#: Liebe (2002): the total irradiance of an m = 0 star, 2.96e-14 W per mm^2 = 2.96e-8 W m^-2.
#: Dzamba & Enright print "2.96e-14 W/m^2", but their own derivation, the solar constant
#: 1.3 kW m^-2 divided by 4.2e10, gives 3.1e-8 W m^-2: the printed figure is per mm^2. With
#: W m^-2 the model would predict 1e6 times fewer electrons than Reed's, not the "approximately
#: twice" more that the paper reports (sec. 2.2); with W mm^-2 it predicts 2.2 times more.
LIEBE_ZERO_MAG_IRRADIANCE_W_M2 = 2.96e-8
#: Liebe: temperature of the zero-magnitude reference black body, K
LIEBE_TEMPERATURE_K = 5800.0
#: Reed (1993): photon flux of a zero-magnitude A star, photons m^-2 s^-1
REED_PHI0_PHOTONS_M2_S = 1.8e10

MODELS = ("liebe", "reed", "blackbody")

QeFunction = Callable[[np.ndarray], np.ndarray]


def _grid(passband_nm: tuple[float, float], n: int = 2001) -> np.ndarray:
    lo, hi = passband_nm
    return np.linspace(lo, hi, n) * 1e-9


@functools.cache
def _liebe_reference_spectrum_shape() -> tuple[float, float]:
    """(scale, _) such that scale * M_e(5800 K, lambda) integrates to 2.96e-14 W m^-2."""
    # integral of the black-body exitance over all wavelengths: sigma T^4 (Stefan-Boltzmann)
    sigma = 2 * np.pi**5 * BOLTZMANN_J_K**4 / (15 * PLANCK_J_S**3 * SPEED_OF_LIGHT_M_S**2)
    return LIEBE_ZERO_MAG_IRRADIANCE_W_M2 / (sigma * LIEBE_TEMPERATURE_K**4), 0.0


def liebe_zero_mag_electron_rate(qe: QeFunction, passband_nm=(400.0, 800.0)) -> float:
    """S_0 of eq. 5: photoelectrons per second per m^2 of aperture from an m = 0 star."""
    lam = _grid(passband_nm)
    scale, _ = _liebe_reference_spectrum_shape()
    irradiance = scale * spectral_exitance(LIEBE_TEMPERATURE_K, lam)  # I_0(lambda), eq. 3
    photons = irradiance / (PLANCK_J_S * SPEED_OF_LIGHT_M_S / lam)  # P_0, eq. 4
    return float(np.trapezoid(qe(lam) * photons, lam))


def liebe_electrons(
    magnitude,
    *,
    diameter_m,
    exposure_s,
    qe: QeFunction,
    passband_nm=(400.0, 800.0),
    transmission: float = 1.0,
):
    """Photoelectrons by the Liebe model, eq. 6: (1/4) t_e pi D^2 S_0 / 2.5^m.

    Parameters
    ----------
    magnitude : float or array_like
        Visual magnitudes of the stars.
    diameter_m : float
        Aperture diameter, m.
    exposure_s : float
        Exposure, s.
    qe : callable
        Quantum efficiency as a function of wavelength (m).
    passband_nm : (float, float)
        Wavelength range integrated, nm.
    transmission : float
        Optical throughput (0-1].

    Returns
    -------
    float or ndarray
        Expected photoelectrons, same shape as ``magnitude``.
    """
    s0 = liebe_zero_mag_electron_rate(qe, passband_nm)
    m = np.asarray(magnitude, dtype=float)
    return transmission * aperture_area_m2(diameter_m) * exposure_s * s0 / 2.5**m


def reed_electrons(magnitude, *, diameter_m, exposure_s, qe_mean, transmission: float = 1.0):
    """Photoelectrons by the Reed model, eq. 8: (1/4) eta_Q t_e pi D^2 phi_0 10^(-0.4 m).

    Parameters
    ----------
    magnitude : float or array_like
        Visual magnitudes of the stars.
    diameter_m : float
        Aperture diameter, m.
    exposure_s : float
        Exposure, s.
    qe_mean : float
        Mean quantum efficiency over the passband.
    transmission : float
        Optical throughput (0-1].

    Returns
    -------
    float or ndarray
        Expected photoelectrons, same shape as ``magnitude``.
    """
    m = np.asarray(magnitude, dtype=float)
    return (
        transmission
        * qe_mean
        * exposure_s
        * aperture_area_m2(diameter_m)
        * REED_PHI0_PHOTONS_M2_S
        * 10.0 ** (-0.4 * m)
    )


def blackbody_electrons(
    dilution,
    temperature_k,
    *,
    diameter_m,
    exposure_s,
    qe: QeFunction,
    passband_nm=(400.0, 800.0),
    transmission: float = 1.0,
):
    """Photoelectrons from each star's own black body through the QE curve (eq. 12 x QE).

    Parameters
    ----------
    dilution : float or array_like
        Geometric dilution factor C of each star (dimensionless).
    temperature_k : float or array_like
        Black-body temperature of each star, K.
    diameter_m : float
        Aperture diameter, m.
    exposure_s : float
        Exposure, s.
    qe : callable
        Quantum efficiency as a function of wavelength (m).
    passband_nm : (float, float)
        Wavelength range integrated, nm.
    transmission : float
        Optical throughput (0-1].

    Returns
    -------
    ndarray
        Expected photoelectrons, the broadcast shape of ``dilution`` and ``temperature_k``.
    """
    lam = _grid(passband_nm, 801)
    n = photons_per_wavelength(
        dilution, temperature_k, lam, diameter_m=diameter_m, exposure_s=exposure_s
    )
    return transmission * np.trapezoid(n * qe(lam), lam, axis=-1)


@dataclass(frozen=True, kw_only=True)
class Sensitivity:
    """Photoelectrons per star for one sensor and one model.

    Parameters
    ----------
    model : {"liebe", "reed", "blackbody"}
    diameter_m, exposure_s : float
        Aperture D (m) and exposure (s).
    qe : callable
        QE at wavelengths in metres (0..1).
    qe_mean : float
        Mean QE over the passband (Reed).
    passband_nm : (float, float)
    transmission : float
    colour : str
        Colour system of the black-body model (default B-V).
    """

    model: str
    diameter_m: float
    exposure_s: float
    qe: QeFunction
    qe_mean: float
    passband_nm: tuple[float, float] = (400.0, 800.0)
    transmission: float = 1.0
    colour: str = "B-V"

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise InputError(
                f"unknown sensitivity model {self.model!r}; choose {', '.join(MODELS)}"
            )
        for name in ("diameter_m", "exposure_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise InputError(f"{name} must be a finite number > 0, got {v!r}")

    @classmethod
    def for_sensor(cls, sensor, model: str = "reed", colour: str = "B-V") -> Sensitivity:
        """Return the model for a :class:`~starsense.sensor.Sensor` (any object with its fields)."""
        det = sensor.detector
        return cls(
            model=model,
            diameter_m=sensor.optics.aperture_m,
            exposure_s=sensor.exposure_s,
            qe=det.qe,
            qe_mean=det.mean_qe,
            passband_nm=tuple(det.passband_nm),
            transmission=sensor.optics.transmission,
            colour=colour,
        )

    def electrons(self, magnitude, colour_index=None) -> np.ndarray:
        """Return the expected photoelectrons for stars of ``magnitude`` (and colour, "blackbody").

        For "blackbody", ``magnitude`` is in the colour system's magnitude band (V for B-V) and
        ``colour_index`` is required; the black body is fitted by Fialho & Mortari sec. 2.5-2.6.
        """
        m = np.asarray(magnitude, dtype=float)
        if self.model == "reed":
            return reed_electrons(
                m,
                diameter_m=self.diameter_m,
                exposure_s=self.exposure_s,
                qe_mean=self.qe_mean,
                transmission=self.transmission,
            )
        if self.model == "liebe":
            return liebe_electrons(
                m,
                diameter_m=self.diameter_m,
                exposure_s=self.exposure_s,
                qe=self.qe,
                passband_nm=self.passband_nm,
                transmission=self.transmission,
            )
        if colour_index is None:
            raise InputError("the blackbody sensitivity model needs each star's colour index")
        t, c = ColourModel(self.colour).fit(m, colour_index)
        return blackbody_electrons(
            c,
            t,
            diameter_m=self.diameter_m,
            exposure_s=self.exposure_s,
            qe=self.qe,
            passband_nm=self.passband_nm,
            transmission=self.transmission,
        )
