"""The sensor's optics: focal length, aperture, throughput, principal point and distortion."""

from __future__ import annotations

from dataclasses import dataclass

from starsense.errors import InputError
from starsense.sensor._fields import check_field

__all__ = ["Optics"]


#: the fastest focal ratio a lens in air can have: N = 1 / (2 NA) with the numerical aperture
#: NA = n sin(theta) <= 1 (Born & Wolf, Principles of Optics, sec. 4.2.3; the aplanatic limit)
MIN_F_NUMBER = 0.5


@dataclass(frozen=True, kw_only=True)
class Optics:
    """Pinhole optics with optional Brown-Conrady distortion and a principal-point offset.

    Attributes
    ----------
    focal_length_m : float
        Effective focal length, m.
    aperture_m : float
        Entrance-pupil diameter D, m.
    transmission : float
        Optical throughput, 0..1 (multiplies the detected photons).
    distortion_k1, distortion_k2 : float
        Radial distortion r_d = r (1 + k1 r^2 + k2 r^4), r the ideal image radius in units of
        the focal length (tan of the off-axis angle).
    distortion_p1, distortion_p2 : float
        Decentring (tangential) distortion, Brown-Conrady
        (:mod:`starsense.geometry.distortion`).
    principal_offset_x_px, principal_offset_y_px : float
        Offset of the principal point (where the optical axis meets the detector, the centre
        of the distortion) from the detector centre, along columns and rows, px.
    distortion_residual_px : float
        What the distortion calibration leaves: rms error of a star's position per axis, px
        (the residual of ``starsense calibrate``). Rendered frames displace each star by it
        (independent per star), the datasheet's budget propagates it (field-of-view spatial
        error).
    psf_sigma_corner_px : float
        Gaussian PSF sigma in the detector's corners, px (0: the detector's ``psf_sigma_px``
        everywhere). Between the centre and the corners the sigma grows with the square of the
        distance from the centre (field curvature, defocus off axis).
    """

    focal_length_m: float
    aperture_m: float
    transmission: float = 1.0
    distortion_k1: float = 0.0
    distortion_k2: float = 0.0
    distortion_p1: float = 0.0
    distortion_p2: float = 0.0
    principal_offset_x_px: float = 0.0
    principal_offset_y_px: float = 0.0
    distortion_residual_px: float = 0.0
    psf_sigma_corner_px: float = 0.0

    def __post_init__(self) -> None:
        check_field("optics", "focal_length_m", self.focal_length_m, 0, 10, lo_open=True)
        check_field("optics", "aperture_m", self.aperture_m, 0, 10, lo_open=True)
        check_field("optics", "transmission", self.transmission, 0, 1, lo_open=True)
        f_number = self.focal_length_m / self.aperture_m
        if f_number < MIN_F_NUMBER:
            raise InputError(
                f"optics: f-number focal_length_m / aperture_m = {self.focal_length_m:g} / "
                f"{self.aperture_m:g} = f/{f_number:.3g} is below f/{MIN_F_NUMBER:g}, the "
                "fastest any lens in air can be (N = 1 / (2 NA), NA <= 1)"
            )
        check_field("optics", "distortion_k1", self.distortion_k1, -10, 10)
        check_field("optics", "distortion_k2", self.distortion_k2, -10, 10)
        check_field("optics", "distortion_p1", self.distortion_p1, -1, 1)
        check_field("optics", "distortion_p2", self.distortion_p2, -1, 1)
        check_field("optics", "principal_offset_x_px", self.principal_offset_x_px, -1e5, 1e5)
        check_field("optics", "principal_offset_y_px", self.principal_offset_y_px, -1e5, 1e5)
        check_field("optics", "distortion_residual_px", self.distortion_residual_px, 0, 100)
        check_field("optics", "psf_sigma_corner_px", self.psf_sigma_corner_px, 0, 100)

    @property
    def distortion(self) -> tuple[float, float, float, float]:
        """(k1, k2, p1, p2), Brown-Conrady (:mod:`starsense.geometry.distortion`)."""
        return (self.distortion_k1, self.distortion_k2, self.distortion_p1, self.distortion_p2)

    @property
    def has_distortion(self) -> bool:
        """Whether any distortion coefficient is non-zero."""
        return any(self.distortion)
