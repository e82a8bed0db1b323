"""Sky geometry: attitudes and (RA, Dec, roll), points and tracks on the sphere, fields of view.

The frame conventions of the whole package are written down once, in
:mod:`starsense.geometry.attitude`.
"""

from starsense.geometry.attitude import (
    angular_separation,
    attitude_from_radec_roll,
    boresight,
    east_north,
    radec_roll_from_attitude,
    radec_to_vectors,
    small_rotation_angles,
    vectors_to_radec,
)
from starsense.geometry.fov import CircularFov, RectangularFov, count_in_fov
from starsense.geometry.sampling import (
    GOLDEN_ANGLE_RAD,
    fibonacci_sphere,
    great_circle_track,
    random_attitudes,
    track_attitudes,
)

__all__ = [
    "GOLDEN_ANGLE_RAD",
    "CircularFov",
    "RectangularFov",
    "angular_separation",
    "attitude_from_radec_roll",
    "boresight",
    "count_in_fov",
    "east_north",
    "fibonacci_sphere",
    "great_circle_track",
    "radec_roll_from_attitude",
    "radec_to_vectors",
    "random_attitudes",
    "small_rotation_angles",
    "track_attitudes",
    "vectors_to_radec",
]
