"""The point-spread function's shape, as a sensor TOML gives it (its width is the detector's).

The ``[psf]`` table of a sensor TOML selects the profile the forward model
(:mod:`starsense.model`) renders, fits and predicts with. The width stays
``detector.psf_sigma_px``: for every shape it is the sigma of the Gaussian of the same full width
at half maximum (FWHM = 2 sqrt(2 ln 2) sigma), so a TOML that gives only the width describes a
Gaussian, and one that adds ``kind = "moffat"`` keeps the same core and adds the wings::

    [psf]
    kind = "moffat"          # "gaussian" (default), "moffat", "airy", "empirical"
    moffat_beta = 2.5        # Moffat: (1 + r^2 / alpha^2)^-beta
    airy_obscuration = 0.0   # Airy: central obstruction, fraction of the aperture's diameter
    file = "my_psf.npy"      # empirical: a 2-D array (.npy or FITS), the PSF sampled on a grid
    oversampling = 4         #   of 1 / oversampling px, centred, any normalisation
    fit_width = false        # the solver fits the PSF's width as well (the optics uncertain)

``radius_px`` bounds the profile: light beyond it (an Airy or Moffat wing) is not drawn or
modelled; 0 chooses it from the shape (:mod:`starsense.model.psf`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from starsense.errors import InputError
from starsense.sensor._fields import check_field

__all__ = ["FWHM_PER_SIGMA", "PSF_KINDS", "PSFSpec", "psf_from_table"]

#: full width at half maximum of a Gaussian, in sigmas: 2 sqrt(2 ln 2)
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))
PSF_KINDS = ("gaussian", "moffat", "airy", "empirical")
#: largest empirical PSF array, samples per side (a 64 px stamp at 16x oversampling)
MAX_EMPIRICAL_SIDE = 1024


@dataclass(frozen=True, kw_only=True)
class PSFSpec:
    """The shape of the point-spread function (module docstring).

    Attributes
    ----------
    kind : {"gaussian", "moffat", "airy", "empirical"}
        The profile.
    moffat_beta : float
        Moffat's power, in (1, 20] (2.5-4.8 for real optics; large beta tends to a Gaussian).
    airy_obscuration : float
        Airy: the central obstruction's diameter over the aperture's, in [0, 0.9].
    samples : ndarray or None
        Empirical: the PSF sampled on a square grid of ``1 / oversampling`` px, its centre at the
        array's centre; normalised to unit sum here.
    oversampling : int
        Empirical: samples per pixel, 1-32.
    source : str
        Where the empirical samples came from (a file name), for messages.
    fit_width : bool
        The solver fits the width (a scale of the profile) along with the attitude.
    radius_px : float
        The profile's extent, px (0: chosen from the shape).
    """

    kind: str = "gaussian"
    moffat_beta: float = 2.5
    airy_obscuration: float = 0.0
    samples: np.ndarray | None = field(default=None, compare=False, repr=False)
    oversampling: int = 4
    source: str = ""
    fit_width: bool = False
    radius_px: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in PSF_KINDS:
            raise InputError(f"psf.kind must be one of {', '.join(PSF_KINDS)}, got {self.kind!r}")
        check_field("psf", "moffat_beta", self.moffat_beta, 1.0, 20.0, lo_open=True)
        check_field("psf", "airy_obscuration", self.airy_obscuration, 0.0, 0.9)
        check_field("psf", "oversampling", self.oversampling, 1, 32, integer=True)
        check_field("psf", "radius_px", self.radius_px, 0.0, 200.0)
        if not isinstance(self.fit_width, bool):
            raise InputError(f"psf.fit_width must be true or false, got {self.fit_width!r}")
        if self.kind == "empirical":
            object.__setattr__(self, "samples", _checked_samples(self.samples, self.source))
        elif self.samples is not None:
            raise InputError(f"psf.file is for kind = 'empirical', not {self.kind!r}")

    @property
    def is_gaussian(self) -> bool:
        """True for the Gaussian profile (exact pixel integrals, the fast path)."""
        return self.kind == "gaussian"

    def describe(self) -> str:
        """One phrase naming the profile, for reports."""
        if self.kind == "moffat":
            return f"Moffat (beta {self.moffat_beta:g})"
        if self.kind == "airy":
            obs = self.airy_obscuration
            return "Airy" + (f" (obscuration {obs:g})" if obs else "")
        if self.kind == "empirical":
            return f"empirical ({self.source or 'array'}, {self.oversampling}x oversampled)"
        return "Gaussian"


def _checked_samples(samples, source: str) -> np.ndarray:
    """Return an empirical PSF array as a finite, non-negative, unit-sum float array."""
    where = f"psf.file {source}" if source else "psf.samples"
    if samples is None:
        raise InputError("psf.kind = 'empirical' needs psf.file (a .npy or FITS array)")
    a = np.asarray(samples, dtype=float)
    if a.ndim != 2 or min(a.shape) < 3:
        raise InputError(f"{where}: a PSF must be a 2-D array of at least 3 x 3, got {a.shape}")
    if max(a.shape) > MAX_EMPIRICAL_SIDE:
        raise InputError(
            f"{where}: {a.shape[0]} x {a.shape[1]} samples, more than {MAX_EMPIRICAL_SIDE} a side"
        )
    if not np.isfinite(a).all():
        raise InputError(f"{where}: the PSF holds NaN or infinite values")
    a = np.clip(a, 0.0, None)
    total = a.sum()
    if total <= 0.0:
        raise InputError(f"{where}: the PSF has no positive value")
    out = a / total
    out.setflags(write=False)
    return out


def _read_array(path: Path) -> np.ndarray:
    """Read a PSF array from a .npy or FITS file."""
    if not path.is_file():
        raise InputError(f"psf.file: no such file {path}")
    if path.suffix.lower() == ".npy":
        try:
            return np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise InputError(f"psf.file {path}: not a NumPy array file ({exc})") from None
    from astropy.io import fits

    try:
        with fits.open(path) as hdul:
            for hdu in hdul:
                if hdu.data is not None:
                    return np.asarray(hdu.data, dtype=float)
    except OSError as exc:
        raise InputError(f"psf.file {path}: not a FITS file ({exc})") from None
    raise InputError(f"psf.file {path}: no image in the FITS file")


_KEYS = {
    "kind",
    "moffat_beta",
    "airy_obscuration",
    "file",
    "oversampling",
    "fit_width",
    "radius_px",
}


def psf_from_table(table, source: str) -> PSFSpec:
    """Build a :class:`PSFSpec` from a TOML ``[psf]`` table.

    Parameters
    ----------
    table : dict
        The table.
    source : str
        The TOML file (an empirical ``file`` is relative to its folder) or a preset's name.

    Raises
    ------
    InputError
        Not a table, an unknown key, a bad value or an unreadable PSF file.
    """
    if not isinstance(table, dict):
        raise InputError(f"[psf] must be a table, got {type(table).__name__}")
    unknown = sorted(set(table) - _KEYS)
    if unknown:
        raise InputError(f"[psf]: unknown key(s) {', '.join(unknown)}; known: {', '.join(_KEYS)}")
    args = {k: v for k, v in table.items() if k != "file"}
    kind = args.get("kind", "gaussian")
    if not isinstance(kind, str):
        raise InputError(f"psf.kind must be text, got {kind!r}")
    if "file" in table:
        name = table["file"]
        if not isinstance(name, str) or not name:
            raise InputError(f"psf.file must be a file name, got {name!r}")
        path = Path(name)
        if not path.is_absolute():
            path = Path(source).parent / path
        args["samples"] = _read_array(path)
        args["source"] = str(name)
    return PSFSpec(**args)
