"""The forward model: the expected pixels of a frame, used three ways (render, fit, predict).

For an attitude, a body rate and an exposure, the expected electrons in each pixel around the
stars in view (the PSF integrated over the pixel and along the star's track, background,
detector response and its variance), with their derivatives with respect to the attitude, the
rate, each star's flux and the background. The renderer draws noise on it
(:mod:`starsense.render`), the solver fits it by maximum likelihood (:mod:`starsense.solve`) and
the datasheet sums its Fisher information over the sky (:mod:`starsense.analysis.datasheet`).

Modules: :mod:`~starsense.model.psf` (the pixel-integrated PSF of each shape),
:mod:`~starsense.model.tracks` (where each star is during the exposure, and how that moves with
the attitude and rate), :mod:`~starsense.model.boxes` (where each star's window lies and
whether a fit can hold them), :mod:`~starsense.model.windows` (the expected pixels of groups of
stars and their Jacobian), :mod:`~starsense.model.fit` (maximum likelihood and the Fisher
information).
"""

from starsense.model.psf import PixelPSF, pixel_psf, psf_of

__all__ = ["PixelPSF", "pixel_psf", "psf_of"]
