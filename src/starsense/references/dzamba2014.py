"""Published numbers of Dzamba & Enright 2014 (the ST-16 star tracker).

Dzamba, T.; Enright, J. "Ground Testing Strategies for Verifying the Slew Rate Tolerance of Star
Trackers", *Sensors* 14, 3939 (2014); plain text in ``shared/papers/001_8e2672462af8c6b1.txt``.
The report prints these beside its own numbers and the tests check against them. Nothing here is
computed at import; the one derived table (:data:`TABLE2_IMPLIED_MT`) says how it was obtained
and a test recomputes it. Angles are given in the paper's units (degrees, deg/s), as the paper
prints them.
"""

from __future__ import annotations

__all__ = [
    "BSC5_V575_STARS",
    "DETECTION_INTEGRATED_COUNTS",
    "DETECTION_LIT_PIXEL_COUNTS",
    "DETECTION_MIN_PIXELS",
    "FIG11_LIEBE",
    "FIG11_REED",
    "GAIN_COUNTS_PER_E",
    "HALF_FOV_DEG",
    "MAX_MAG",
    "N_ORIENTATIONS",
    "QUOTED_MAGNITUDES",
    "STATIC_AVAILABILITY_N3",
    "TABLE2",
    "TABLE2_IMPLIED_MT",
    "TABLE2_RATES_DEG_S",
    "TRACK_SAMPLES",
]

#: sec. 1.2: the ST-16 catalogue holds the stars of V <= 5.75, also the static detection threshold
MAX_MAG = 5.75
#: sec. 1.2: stars of the ST-16 catalogue drawn from the Yale Bright Star Catalogue
BSC5_V575_STARS = 3746
#: sec. 1.2: the ST-16 "half-axis FOV of 7.5 deg", deg
HALF_FOV_DEG = 7.5
#: sec. 1.2: orientations tested for the spatial availability (Marantis distribution)
N_ORIENTATIONS = 10_000
#: sec. 1.2: spatial static availability with N_min = 3, m_t = 5.75: "> 99.9 %" (a fraction)
STATIC_AVAILABILITY_N3 = 0.999
#: sec. 4: orientations sampled along each track, N_track
TRACK_SAMPLES = 1_000

#: sec. 1.2: detection logic of the ST-16: lit pixel threshold (counts of 4,095)
DETECTION_LIT_PIXEL_COUNTS = 120
#: sec. 1.2: minimum number of contiguous lit pixels
DETECTION_MIN_PIXELS = 6
#: sec. 1.2: minimum integrated intensity, counts
DETECTION_INTEGRATED_COUNTS = 1000
#: sec. 2.2 and 3.1: detector gain, counts per electron
GAIN_COUNTS_PER_E = 6.5

#: sec. 3.1: magnitudes whose tolerable slew rate the discussion of Figs. 9-10 quotes
QUOTED_MAGNITUDES = (3.0, 4.0, 5.0, 5.75)

#: sec. 3.1 (Fig. 11), Reed model: rate (deg/s) -> approximate spatial dynamic availability
#: (N_min = 2, N_min = 3) as fractions ("~90 %" / "~80 %" at 1 deg/s, "~55 %" / "~30 %" at 2)
FIG11_REED: dict[float, tuple[float, float]] = {1.0: (0.90, 0.80), 2.0: (0.55, 0.30)}
#: sec. 3.1 (Fig. 11), Liebe model: rate (deg/s) -> lower bound on the availability for both
#: N_min = 2 and 3 ("~100 %" at 1 deg/s, "> 90 %" at 2 deg/s), fractions
FIG11_LIEBE: dict[float, float] = {1.0: 0.99, 2.0: 0.90}

#: Table 2: rate (deg/s) -> (N_min = 2, N_min = 3) pairs of spatial dynamic, along-track mean,
#: max and min availability, in percent.
TABLE2: dict[float, dict[str, tuple[float, float]]] = {
    1.0: {"spatial": (93.3, 80.9), "mean": (95.5, 86.9), "max": (100.0, 100.0),
          "min": (86.2, 72.0)},
    1.5: {"spatial": (79.1, 58.6), "mean": (84.5, 66.6), "max": (98.0, 93.9),
          "min": (65.4, 45.6)},
    2.0: {"spatial": (50.8, 27.6), "mean": (67.7, 45.3), "max": (91.1, 78.0),
          "min": (45.9, 23.5)},
    3.0: {"spatial": (38.9, 14.2), "mean": (49.8, 26.6), "max": (80.1, 57.9),
          "min": (28.2, 8.0)},
}  # fmt: skip
#: the slew rates of Table 2 and Figs. 16-17, deg/s
TABLE2_RATES_DEG_S = tuple(TABLE2)

#: Derived from Table 2, not printed in the paper: rate (deg/s) -> (m_t implied by the N_min = 2
#: spatial value, m_t implied by the N_min = 3 value), mag. Each is the threshold at which the
#: spatial availability on BSC5 (V <= 5.75, the 7.5 deg half-axis field, 10,000 pointings: the
#: paper's sec. 1.2 set-up) equals Table 2's percentage
#: (starsense.analysis.availability.implied_threshold; tests/analysis/test_slew_study.py
#: recomputes them). That the two agree (to 0.02 mag at 1-2 deg/s, 0.12 at 3 deg/s) says our
#: sky is the paper's; their mean is the paper's threshold curve m_t(w) read back from Table 2.
TABLE2_IMPLIED_MT: dict[float, tuple[float, float]] = {
    1.0: (4.78, 4.76),
    1.5: (4.39, 4.39),
    2.0: (3.86, 3.87),
    3.0: (3.65, 3.53),
}
