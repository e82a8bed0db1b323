"""The sensor's detector: pixels, quantum efficiency, noise, gain and ADC."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense._validate import show
from starsense.errors import InputError
from starsense.sensor._fields import check_field

__all__ = ["Detector"]


@dataclass(frozen=True, kw_only=True)
class Detector:
    """Image detector.

    Attributes
    ----------
    columns, rows : int
        Pixels across (x) and down (y).
    pixel_pitch_m : float
        Pixel size, m.
    qe_mean : float
        Mean quantum efficiency over ``passband_nm`` (Reed model; used when no curve is given).
    qe_curve_nm, qe_curve : tuple of float
        Optional QE curve: wavelengths (nm, increasing) and QE (0..1).
    passband_nm : (float, float)
        Wavelength range the detector responds to, nm (paper: 400-800 nm).
    full_well_e : float
        Full-well capacity, electrons (signal clips here before the ADC).
    gain_counts_per_e : float
        Conversion gain, counts per electron, within [1e-4, 1e4].
    read_noise_e : float
        Read noise, electrons rms.
    dark_current_e_s : float
        Dark current, electrons per pixel per second.
    bias_counts : float
        Offset added before quantisation, counts.
    bit_depth : int
        ADC bits (1..32): counts saturate at 2^bits - 1.
    psf_sigma_px : float
        Standard deviation of the static Gaussian PSF, pixels.
    prnu_fraction : float
        Photo-response non-uniformity: rms pixel-to-pixel gain spread, a fraction (0.01 = 1 %).
    dsnu_e : float
        Dark-signal non-uniformity: rms pixel-to-pixel offset left after the dark frame is
        subtracted, electrons.
    hot_pixel_fraction : float
        Fraction of the pixels that are hot (dark current ``hot_pixel_e_s``).
    hot_pixel_e_s : float
        Dark current of a hot pixel, electrons per second.
    """

    columns: int
    rows: int
    pixel_pitch_m: float
    gain_counts_per_e: float
    read_noise_e: float
    bit_depth: int
    psf_sigma_px: float
    qe_mean: float = 0.5
    qe_curve_nm: tuple[float, ...] = ()
    qe_curve: tuple[float, ...] = ()
    passband_nm: tuple[float, float] = (400.0, 800.0)
    full_well_e: float = 1e5
    dark_current_e_s: float = 0.0
    bias_counts: float = 0.0
    prnu_fraction: float = 0.0
    dsnu_e: float = 0.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_e_s: float = 1000.0

    def __post_init__(self) -> None:
        check_field("detector", "columns", self.columns, 1, 100_000, integer=True)
        check_field("detector", "rows", self.rows, 1, 100_000, integer=True)
        check_field("detector", "pixel_pitch_m", self.pixel_pitch_m, 0, 1e-3, lo_open=True)
        # 1e-4 counts/e (10,000 e per count) to 1e4: beyond any CCD/CMOS/EMCCD; 1e-30 is a typo
        check_field("detector", "gain_counts_per_e", self.gain_counts_per_e, 1e-4, 1e4)
        check_field("detector", "read_noise_e", self.read_noise_e, 0, 1e4)
        check_field("detector", "bit_depth", self.bit_depth, 1, 32, integer=True)
        check_field("detector", "psf_sigma_px", self.psf_sigma_px, 0, 100, lo_open=True)
        check_field("detector", "qe_mean", self.qe_mean, 0, 1, lo_open=True)
        check_field("detector", "full_well_e", self.full_well_e, 0, 1e9, lo_open=True)
        check_field("detector", "dark_current_e_s", self.dark_current_e_s, 0, 1e9)
        check_field("detector", "bias_counts", self.bias_counts, 0, 2.0**self.bit_depth - 1)
        check_field("detector", "prnu_fraction", self.prnu_fraction, 0, 0.5)
        check_field("detector", "dsnu_e", self.dsnu_e, 0, 1e4)
        check_field("detector", "hot_pixel_fraction", self.hot_pixel_fraction, 0, 0.1)
        check_field("detector", "hot_pixel_e_s", self.hot_pixel_e_s, 0, 1e9)
        self._check_spectrum()

    def _check_spectrum(self) -> None:
        """Check the passband and the optional QE curve."""
        for name in ("passband_nm", "qe_curve_nm", "qe_curve"):
            value = getattr(self, name)
            if not isinstance(value, tuple | list):
                example = "[400.0, 800.0]" if name == "passband_nm" else "[400.0, 500.0, ...]"
                raise InputError(
                    f"detector.{name} must be a list of numbers, e.g. {example}; got {show(value)}"
                )
        for i, nm in enumerate(self.qe_curve_nm):
            check_field("detector", f"qe_curve_nm[{i}]", nm, 50, 30000)
        if len(self.passband_nm) != 2:
            raise InputError(f"detector.passband_nm must be [low, high], got {self.passband_nm!r}")
        lo, hi = self.passband_nm
        check_field("detector", "passband_nm[0]", lo, 50, 30000)
        check_field("detector", "passband_nm[1]", hi, lo, 30000, lo_open=True)
        if len(self.qe_curve_nm) != len(self.qe_curve):
            raise InputError(
                f"detector.qe_curve_nm ({len(self.qe_curve_nm)} values) and detector.qe_curve "
                f"({len(self.qe_curve)} values) must have the same length"
            )
        if self.qe_curve:
            if len(self.qe_curve) < 2:
                raise InputError("detector.qe_curve needs at least 2 points")
            if np.any(np.diff(self.qe_curve_nm) <= 0):
                raise InputError("detector.qe_curve_nm must be strictly increasing")
            for i, q in enumerate(self.qe_curve):
                check_field("detector", f"qe_curve[{i}]", q, 0, 1)

    @property
    def saturation_counts(self) -> int:
        """Largest count the ADC can output, 2^bits - 1."""
        return 2**self.bit_depth - 1

    @property
    def clip_e(self) -> float:
        """Signal at which a pixel clips, electrons: the full well or the ADC's top (less bias)."""
        return min(
            self.full_well_e, (self.saturation_counts - self.bias_counts) / self.gain_counts_per_e
        )

    def qe(self, wavelength_m) -> np.ndarray:
        """Return the QE at the given wavelengths.

        The curve if one is given, else ``qe_mean`` inside the passband and zero outside it.

        Parameters
        ----------
        wavelength_m : float or array_like
            Wavelengths, m.

        Returns
        -------
        ndarray
            Quantum efficiency (0..1), the shape of ``wavelength_m``.
        """
        lam_nm = np.asarray(wavelength_m, dtype=float) * 1e9
        if self.qe_curve:
            return np.interp(lam_nm, self.qe_curve_nm, self.qe_curve, left=0.0, right=0.0)
        lo, hi = self.passband_nm
        return np.where((lam_nm >= lo) & (lam_nm <= hi), self.qe_mean, 0.0)

    @property
    def mean_qe(self) -> float:
        """Mean QE over the passband (the Reed model's eta_Q)."""
        if not self.qe_curve:
            return self.qe_mean
        lo, hi = self.passband_nm
        lam = np.linspace(lo, hi, 2001) * 1e-9
        return float(np.mean(self.qe(lam)))
