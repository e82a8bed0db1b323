"""ECSS-E-ST-60-20C error classes, and how each acts at a body rate.

ECSS-E-ST-60-20C splits a star sensor's measurement error into the bias, the thermo-elastic
error, the field-of-view (low-frequency) spatial error, the pixel (high-frequency) spatial
error, the temporal noise and the aberration of light. The spatial errors are fixed functions
of where a star falls on the detector: while the spacecraft points inertially every star stays
on its pixel and they are **biases** (constant over the observation); under a slew the stars
move across the detector and the same errors become **noise**, low-frequency for the field of
view's (a star crosses the field in ``field / rate``) and high-frequency for the pixel's (a star
crosses a pixel in ``pixel / rate``). :func:`acting` says which, and its period.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CLASSES", "Acting", "acting"]

#: ECSS class key -> its name in ECSS-E-ST-60-20C
CLASSES = {
    "bias": "bias error (BE)",
    "thermo_elastic": "thermo-elastic error (TEE)",
    "fov_spatial": "field-of-view spatial error (FOV SE, low-frequency spatial)",
    "pixel_spatial": "pixel spatial error (PSE, high-frequency spatial)",
    "temporal_noise": "temporal noise (TE)",
    "aberration": "aberration of light (AE)",
}


@dataclass(frozen=True)
class Acting:
    """How an error class acts at one rate.

    Attributes
    ----------
    acts_as : {"bias", "noise"}
        Constant over an inertial observation, or varying within it.
    time_class : str
        ``bias``, ``low_frequency`` (an orbit's or the field crossing's period),
        ``high_frequency`` (a pixel crossing) or ``temporal_noise`` (frame to frame).
    period_s : float or None
        The error's period (field or pixel crossing time), s; None where it is not the rate's.
    """

    acts_as: str
    time_class: str
    period_s: float | None


def acting(ecss_class: str, rate_rad_s: float, *, field_rad: float, pixel_rad: float) -> Acting:
    """Return how an error class acts at a body rate (module docstring).

    Parameters
    ----------
    ecss_class : str
        A key of :data:`CLASSES`.
    rate_rad_s : float
        Body rate, rad/s (>= 0).
    field_rad : float
        The field's width (its narrower side: the shortest crossing), rad.
    pixel_rad : float
        One pixel's angle, rad.

    Returns
    -------
    Acting
    """
    if ecss_class == "temporal_noise":
        return Acting("noise", "temporal_noise", None)
    if ecss_class == "bias":
        return Acting("bias", "bias", None)
    if ecss_class in ("thermo_elastic", "aberration"):
        # the thermal cycle and the observer's velocity change over an orbit (or a year),
        # whatever the attitude does: a bias over any one observation
        return Acting("bias", "low_frequency", None)
    if ecss_class not in ("fov_spatial", "pixel_spatial"):
        raise ValueError(f"unknown ECSS class {ecss_class!r}")
    if rate_rad_s <= 0.0:
        return Acting("bias", "bias", None)
    if ecss_class == "fov_spatial":
        return Acting("noise", "low_frequency", field_rad / rate_rad_s)
    return Acting("noise", "high_frequency", pixel_rad / rate_rad_s)
