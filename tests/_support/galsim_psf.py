"""The PSFs of the GalSim frames (:mod:`galsim_frames`): GalSim profiles of a sensor's PSF width.

PSF width: every kind has the full width at half maximum of the sensor's Gaussian,
``2 sqrt(2 ln 2) detector.psf_sigma_px`` (before the pixel). Airy: ``lam_over_diam`` set so
(with the obscuration asked); Moffat: ``beta`` 2.5 by default; optical: ``galsim.OpticalPSF``
with 0.15 wave of defocus and a little astigmatism, scaled so its FWHM is the same.

Each star is drawn in a square stamp around its track: 5.5 sigma of the Gaussian (light lost
< 1e-7), the radius that holds all but 2e-4 of a Moffat's light (its encircled energy
``1 - (1 + r^2 / alpha^2)^(1 - beta)``), and :data:`WING_RADIUS_FWHM` FWHM for Airy and optical
PSFs, whose wings hold light out to hundreds of FWHM (an Airy disc keeps ~1 % beyond 16 FWHM,
``2 / (pi x)`` at ``x = pi r D / lambda``): that far light, spread over ~10^3 pixels a star at
~10^-5 of its flux each, is not drawn. The truth records each star's ``electrons`` (all its
light) and ``electrons_drawn`` (what its stamp put on the detector).
"""

from __future__ import annotations

import functools
import math

import numpy as np

__all__ = [
    "FWHM_PER_SIGMA",
    "MOFFAT_LOSS",
    "PSF_DEFAULTS",
    "PSF_KINDS",
    "WING_RADIUS_FWHM",
    "psf_profile",
    "stamp_radius_px",
]

#: FWHM of a Gaussian over its sigma, 2 sqrt(2 ln 2)
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))
PSF_KINDS = ("gaussian", "airy", "moffat", "optical")
#: stamp half-width of Airy and optical PSFs, in FWHM (see the module docstring)
WING_RADIUS_FWHM = 16.0
#: light a Moffat stamp may leave out, fraction of the star
MOFFAT_LOSS = 2e-4
#: the defaults of each kind's shape parameters
PSF_DEFAULTS = {
    "gaussian": {},
    "airy": {"obscuration": 0.0},
    "moffat": {"beta": 2.5},
    "optical": {"defocus": 0.15, "astig1": 0.05, "astig2": 0.03, "obscuration": 0.0},
}


def _galsim():
    import galsim

    return galsim


def _gsparams(kind: str):
    """GalSim's accuracy settings for a PSF kind.

    The k-space threshold is 100x tighter than GalSim's default (the drawn pixels of a
    Gaussian then match the exact erf products to ~1e-7 of the peak, 1e-4 by default). So is
    the folding threshold for the kinds whose light is within a few FWHM (Gaussian, Moffat);
    Airy and optical PSFs keep GalSim's 5e-3: their wings reach hundreds of FWHM, and a
    folding of 1e-4 asks for FFTs of 12,288^2; what folds back is light of the far wings spread
    over the FFT's whole area (~1e-8 of the star per pixel). The optical PSF keeps GalSim's
    defaults (an interpolated image of its pupil's FFT, whose sampling sets its accuracy).
    """
    if kind == "optical":  # its pupil's FFT sets its accuracy; tighter settings cost 4x
        return _galsim().GSParams()
    folding = 1e-4 if kind in ("gaussian", "moffat") else 5e-3
    return _galsim().GSParams(folding_threshold=folding, maxk_threshold=1e-5)


def _options(kind: str, options: dict | None) -> dict:
    if kind not in PSF_KINDS:
        raise ValueError(f"unknown psf {kind!r}; choose one of {', '.join(PSF_KINDS)}")
    opts = dict(PSF_DEFAULTS[kind])
    unknown = set(options or {}) - set(opts)
    if unknown:
        raise ValueError(f"psf {kind!r} has no option(s) {sorted(unknown)}; it has {sorted(opts)}")
    opts.update(options or {})
    return opts


@functools.lru_cache(maxsize=32)
def _profile(kind: str, fwhm_px: float, items: tuple):
    galsim, gsp = _galsim(), _gsparams(kind)
    o = dict(items)
    if kind == "gaussian":
        return galsim.Gaussian(fwhm=fwhm_px, gsparams=gsp)
    if kind == "moffat":
        return galsim.Moffat(beta=o["beta"], fwhm=fwhm_px, gsparams=gsp)
    return galsim.Transform(_phase_profile(kind, fwhm_px, o, gsp))  # see below


def _phase_profile(kind, fwhm_px, o, gsp):
    """Airy or optical PSF of ``fwhm_px``.

    Returned inside a ``galsim.Transform`` by the caller: ``OpticalPSF.withFlux`` builds a new
    OpticalPSF (its FFT of the pupil, ~30 ms a star), a Transformation's does not.
    """
    galsim = _galsim()
    # Airy and optical: the shape scales with lam/D (aberrations in waves), so the FWHM does
    if kind == "airy":
        ref = 10.0  # lam/D of the reference, px: well resolved, so its FWHM is exact
        probe = galsim.Airy(lam_over_diam=ref, obscuration=o["obscuration"])
        lod = ref * fwhm_px / probe.calculateFWHM()
        return galsim.Airy(lam_over_diam=lod, obscuration=o["obscuration"], gsparams=gsp)
    aberr = {k: o[k] for k in ("defocus", "astig1", "astig2")}
    # an astigmatic core is not round: its FWHM is that of the disc of the same area above
    # half the peak (calculateFWHM's cut along x gives 25-40 % too wide a PSF here)
    probe = galsim.OpticalPSF(lam_over_diam=1.0, obscuration=o["obscuration"], **aberr)
    fine = probe.drawImage(nx=400, ny=400, scale=0.01, method="no_pixel").array
    lod = fwhm_px / (2.0 * 0.01 * math.sqrt(np.count_nonzero(fine > 0.5 * fine.max()) / math.pi))
    return galsim.OpticalPSF(lam_over_diam=lod, obscuration=o["obscuration"], gsparams=gsp, **aberr)


def psf_profile(kind: str, fwhm_px: float, **options):
    """Return the GalSim profile of unit flux of a PSF kind, in pixel units.

    Parameters
    ----------
    kind : {"gaussian", "airy", "moffat", "optical"}
    fwhm_px : float
        Full width at half maximum before the pixel, px.
    **options
        ``beta`` (moffat), ``obscuration`` (airy, optical), ``defocus``, ``astig1``,
        ``astig2`` (optical, waves): :data:`PSF_DEFAULTS`.

    Returns
    -------
    galsim.GSObject
    """
    opts = _options(kind, options)
    return _profile(kind, float(fwhm_px), tuple(sorted(opts.items())))


def stamp_radius_px(kind: str, fwhm_px: float, **options) -> int:
    """Return the half-width of the square stamp a star of this PSF is drawn in, px."""
    opts = _options(kind, options)
    if kind == "gaussian":
        r = 5.5 * fwhm_px / FWHM_PER_SIGMA
    elif kind == "moffat":
        beta = opts["beta"]
        alpha = fwhm_px / (2.0 * math.sqrt(2.0 ** (1.0 / beta) - 1.0))
        r = alpha * math.sqrt(MOFFAT_LOSS ** (1.0 / (1.0 - beta)) - 1.0)
    else:
        r = WING_RADIUS_FWHM * fwhm_px
    return math.ceil(r) + 1
