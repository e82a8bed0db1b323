"""Published numbers of Fialho & Mortari 2019, "Theoretical Limits of Star Sensor Accuracy".

*Sensors* 19, 5355 (2019). The one copy of the paper's values: the report prints them beside
ours and the tests check ours against them. Angles are radians unless a name says otherwise
(Table 2 is published in milliarcseconds and kept so).
"""

from __future__ import annotations

__all__ = [
    "FIG7_EXTRAPOLATED_RAD",
    "G_INTERVAL",
    "LOW_PHOTON_D2T_M2_S",
    "N_GALAXY",
    "TABLE1_DIAMETER_M",
    "TABLE1_EXPOSURE_S",
    "TABLE1_HKS",
    "TABLE1_UBV",
    "TABLE2_DIAMETER_M",
    "TABLE2_EXPOSURE_S",
    "TABLE2_MAS",
    "TABLE2_TARGETS",
    "TWO_HEAD_DIAMETER_FACTOR",
]

#: the paper's interval for G, rad m^2 s^1/2 (sec. 3.3)
G_INTERVAL = (7e-15, 1e-13)
#: stars in the Galaxy used for the paper's extrapolation (sec. 3.3)
N_GALAXY = 3e11
#: theta_rms at N = 3e11 read off the paper's lower and upper extrapolation curves (Fig. 7,
#: sec. 3.3), rad, for D = 1 m and t = 1 s
FIG7_EXTRAPOLATED_RAD = (1.2e-14, 5.8e-14)

#: Table 1's sensor: D = 10 cm, t = 100 ms
TABLE1_DIAMETER_M = 0.10
TABLE1_EXPOSURE_S = 0.100
#: Table 1, UBV half: name, m_V, B-V, T (K), C, sigma_min,BB (rad)
TABLE1_UBV = (
    ("Vega", 0.030, -0.001, 13231, 2.96e-17, 1.19e-10),
    ("1757132", 11.81, 0.26, 8580, 1.87e-21, 4.42e-8),
    ("Sun", -26.75, 0.65, 5711, 2.42e-5, 1.08e-15),
    ("KF06T2", 13.97, 1.18, 3951, 9.59e-21, 1.36e-7),
    ("VB8", 16.80, 2.01, 2613, 2.01e-20, 2.63e-7),
)
#: Table 1, 2MASS half: name, m_H, H-Ks, T (K), C, sigma_min,BB (rad)
TABLE1_HKS = (
    ("Vega", -0.004, -0.005, 10417, 4.80e-17, 1.70e-10),
    ("1757132", 11.23, 0.02, 8961, 1.94e-21, 3.89e-8),
    ("Sun", -28.24, 0.04, 8059, 1.41e-5, 5.94e-16),
    ("KF06T2", 11.26, 0.10, 6050, 3.72e-21, 7.50e-8),
    ("VB8", 9.17, 0.34, 3282, 1.05e-19, 6.50e-8),
)

#: Table 2's sensor: D = 10 cm, t = 10 ms
TABLE2_DIAMETER_M = 0.10
TABLE2_EXPOSURE_S = 0.010
#: Table 2, mas: FOV diameter (deg) -> (target 1, target 2, both). Computed from the
#: 26,036,431 2MASS stars with J <= 12.575, black bodies from J and H.
TABLE2_MAS = {
    360.0: (0.0073, 0.0073, 0.0051),
    90.0: (0.0369, 0.0202, 0.0152),
    25.0: (0.641, 0.120, 0.0754),
    10.0: (3.29, 1.231, 0.213),
    4.0: (31.6, 10.8, 0.720),
}
#: the two pointings of Table 2: (label, RA in hours, Dec in degrees)
TABLE2_TARGETS = (("target 1", 0.0, 0.0), ("target 2", 6.0, 0.0))
#: sec. 3.5 (Fig. 8): two "ideal" heads fit in a sphere of twice the diameter of one
TWO_HEAD_DIAMETER_FACTOR = 2.0

#: sec. 3.3.2: sensors with D^2 t >= 1e-4 m^2 s come close to the limit
LOW_PHOTON_D2T_M2_S = 1e-4
