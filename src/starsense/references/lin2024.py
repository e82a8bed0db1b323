"""Published numbers of Lin, Qiu, Zhang & Wang 2024 (guide-star distribution).

Lin, Qiu, Zhang & Wang, "Research on Guide Star Distribution of Sub-Arcsecond Attitude
Determination for Microsatellites Reusing Scientific Cameras", *Electronics* 13, 228 (2024).

The values are as printed in the paper, in its units (arcseconds, degrees, percent); code that
computes with them converts at the point of use (:mod:`starsense.units`). Read by the analysis
(defaults), the report (the paper's columns beside ours) and the tests.
"""

from __future__ import annotations

__all__ = [
    "CAMERA_FOV_DEG",
    "CONFIGURATION_ORDER",
    "FIELD_TABLES",
    "LATTICE_STEP",
    "N_GUIDE_STARS",
    "PATTERN_FOVS_DEG",
    "SEGMENT_AREA_V2",
    "TABLE1_PERCENT",
    "TABLE1_SIGMAS_ARCSEC",
    "TABLE1_THRESHOLD_ARCSEC",
    "TABLE3_4_SIGMAS_ARCSEC",
]

SEGMENT_AREA_V2 = 0.57
"""Total area of the four attitude-determination areas, units of V^2 (sec. 2.2, rounded)."""

LATTICE_STEP = 0.07
"""Step of the traversal of the areas, fraction of the science field V (sec. 4)."""

N_GUIDE_STARS = 5
"""Guide stars per placement in the simulation (sec. 4)."""

TABLE1_THRESHOLD_ARCSEC = 0.1
"""Accuracy requirement of Table 1, arcsec."""

TABLE1_SIGMAS_ARCSEC = (0.3, 0.25, 0.2, 0.1, 0.05, 0.02, 0.01)
"""Measurement errors of the simulation (sec. 4, the rows of Table 1), arcsec."""

CONFIGURATION_ORDER = ("one", "two_adjacent", "two_symmetric", "three", "four")
"""The columns of Tables 1, 3 and 4: guide stars in one area, two adjacent, two symmetric,
three and four areas."""

TABLE1_PERCENT: dict[str, tuple[float, ...]] = {
    "one": (0.15, 0.24, 0.44, 1.65, 9.92, 55.82, 73.45),
    "two_adjacent": (11.08, 16.46, 24.45, 54.67, 84.73, 98.60, 99.3),
    "two_symmetric": (7.48, 16.38, 46.10, 94.21, 95.85, 95.89, 95.89),
    "three": (9.04, 16.75, 39.18, 90.94, 99.18, 99.84, 99.84),
    "four": (84.90, 95.97, 98.99, 99.87, 99.87, 99.87, 99.87),
}
"""Table 1: probability (%) of an attitude accuracy better than 0.1 arcsec, per configuration,
rows as :data:`TABLE1_SIGMAS_ARCSEC`."""

CAMERA_FOV_DEG = 2048 * 2.0 / 3600.0
"""Science field V of the observed star patterns 1 and 3 (sec. 5, Table 2), deg: 2048 px at
2 arcsec = 1.138 deg; the 1.6 deg pattern is the lens circle (1.6 / sqrt 2)."""

PATTERN_FOVS_DEG = (1.6, 0.4)
"""Fields of the observed star patterns (Table 2), deg: the lens-circle diameters."""

TABLE3_4_SIGMAS_ARCSEC = (0.2, 0.05)
"""Average measurement errors of Tables 3 and 4, arcsec."""

FIELD_TABLES: dict[str, dict] = {
    "table3": {
        "center_deg": (150.0, 0.0),
        "accuracy_arcsec": {
            0.2: {
                "one": 6.51,
                "two_adjacent": 0.34,
                "two_symmetric": 0.21,
                "three": 0.21,
                "four": 0.08,
            },
            0.05: {
                "one": 18.02,
                "two_adjacent": 0.13,
                "two_symmetric": 0.06,
                "three": 0.10,
                "four": 0.04,
            },
        },
    },
    "table4": {
        "center_deg": (240.0, -80.0),
        "accuracy_arcsec": {
            0.2: {
                "one": 34.04,
                "two_adjacent": 0.42,
                "two_symmetric": 0.21,
                "three": 0.26,
                "four": 0.07,
            },
            0.05: {
                "one": 1.17,
                "two_adjacent": 0.21,
                "two_symmetric": 0.03,
                "three": 0.07,
                "four": 0.03,
            },
        },
    },
}
"""Tables 3 and 4: average attitude accuracy (arcsec) of the 1.6 deg patterns (DSS images) at
the field centres ``center_deg`` (RA, Dec), per average measurement error (arcsec) and
configuration."""
