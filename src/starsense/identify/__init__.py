"""Lost-in-space star identification.

One database, several algorithms behind one interface: an identifier is configured with a
database and called on the camera-frame directions of the detections, brightest first; it
returns an :class:`Identification` (status, attitude, matches, residual, probability of a
false match, timing).

>>> from starsense.catalog import load_catalog
>>> from starsense.identify import HashIdentifier, build_database
>>> db = build_database(load_catalog("hipparcos"), max_fov_rad=0.2)   # cached on disk
>>> result = HashIdentifier(db)(sensor.unproject(det.x, det.y), fov_rad=0.2)  # doctest: +SKIP

==========================  ============================================================
:class:`HashIdentifier`     4-star geometric hashing (tetra3); known or unknown field
:class:`TriangleIdentifier` star triangles against catalogue pairs; known field, >= 3 stars
==========================  ============================================================
"""

from starsense.identify.database import DatabaseParams, IdentificationDatabase, build_database
from starsense.identify.hashing import HashIdentifier
from starsense.identify.patterns import edge_ratios, pattern_edges, thin_by_region
from starsense.identify.result import Identification, identify_ranked
from starsense.identify.triangle import TriangleIdentifier
from starsense.identify.verify import Verifier, false_match_probability

__all__ = [
    "DatabaseParams",
    "HashIdentifier",
    "Identification",
    "IdentificationDatabase",
    "TriangleIdentifier",
    "Verifier",
    "build_database",
    "edge_ratios",
    "false_match_probability",
    "identify_ranked",
    "pattern_edges",
    "thin_by_region",
]
