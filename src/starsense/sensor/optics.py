"""The sensor's optics: pinhole focal length, aperture, throughput and radial distortion."""

from __future__ import annotations

from dataclasses import dataclass

from starsense.sensor._fields import check_field

__all__ = ["Optics"]


@dataclass(frozen=True)
class Optics:
    """Pinhole optics with optional radial distortion.

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
    """

    focal_length_m: float
    aperture_m: float
    transmission: float = 1.0
    distortion_k1: float = 0.0
    distortion_k2: float = 0.0

    def __post_init__(self) -> None:
        check_field("optics", "focal_length_m", self.focal_length_m, 0, 10, lo_open=True)
        check_field("optics", "aperture_m", self.aperture_m, 0, 10, lo_open=True)
        check_field("optics", "transmission", self.transmission, 0, 1, lo_open=True)
        check_field("optics", "distortion_k1", self.distortion_k1, -10, 10)
        check_field("optics", "distortion_k2", self.distortion_k2, -10, 10)
