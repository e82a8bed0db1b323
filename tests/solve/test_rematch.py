"""Every detection held against the identified sky at its own centroid noise."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense.identify.result import Identification
from starsense.solve.rematch import MATCH_SIGMAS, rematched

ARCSEC = math.pi / (180 * 3600)


def _sky(n: int, rng, half_deg: float = 4.0):
    """Stars spread over a small cap about +z (camera = ICRS), far apart from each other."""
    xy = rng.uniform(-1, 1, (n, 2)) * math.radians(half_deg)
    v = np.column_stack([xy, np.ones(n)])
    return v / np.linalg.norm(v, axis=1)[:, None]


def _db(vectors):
    return SimpleNamespace(
        vectors=vectors, ids=np.arange(100, 100 + len(vectors)), tree=cKDTree(vectors)
    )


def _offset(v, angle_rad, rng):
    """``v`` moved by ``angle_rad`` in a random direction normal to it."""
    a = rng.normal(size=3)
    a -= (a @ v) * v
    w = v + angle_rad * a / np.linalg.norm(a)
    return w / np.linalg.norm(w)


def _ident(det, cat, db):
    return Identification(
        "solved", "hashing", rotation=Rotation.identity(),
        detection_index=np.asarray(det), catalog_index=np.asarray(cat),
        catalog_id=db.ids[np.asarray(cat)], residual_rms_rad=0.0, message="matched",
    )  # fmt: skip


def test_faint_true_stars_within_their_own_noise_are_added():
    rng = np.random.default_rng(3)
    stars = _sky(40, rng)
    db = _db(stars)
    sigma = np.full(40, 2.0 * ARCSEC)
    # detections 0-9 matched already; 10-29 true, each 3 of its sigma off (inside the 4-sigma
    # radius); 30-39 true but 6 sigma off (outside: not added)
    det = np.array([_offset(stars[i], (3.0 if i < 30 else 6.0) * sigma[i], rng) for i in range(40)])
    got = rematched(_ident(range(10), range(10), db), db, det, sigma_rad=sigma)
    assert np.array_equal(got.detection_index, np.arange(30))
    assert np.array_equal(got.catalog_index, np.arange(30))  # each with its own star
    assert np.array_equal(got.catalog_id, db.ids[:30])
    assert MATCH_SIGMAS == 4.0  # 1 true pair in 3,000 outside (exp(-8))


def test_ambiguous_and_chance_pairs_are_not_made():
    rng = np.random.default_rng(5)
    stars = _sky(12, rng)
    # a second database star 1 arcsec from star 10: a detection there could be either
    twin = _offset(stars[10], 1.0 * ARCSEC, rng)
    db = _db(np.vstack([stars, twin]))
    sigma = np.full(12, 1.0 * ARCSEC)
    det = stars.copy()
    # detection 11: a faint blob whose sigma is 3 arcmin; it lies on star 11, the only star
    # in its 12 arcmin radius, but at this field's density a random point has a star that
    # close one time in ~60: no evidence
    sigma[11] = math.radians(3.0 / 60.0)
    others = np.delete(db.vectors, 11, axis=0)
    assert np.arccos(np.clip(others @ det[11], -1, 1)).min() > 4.0 * sigma[11]
    got = rematched(_ident(range(10), range(10), db), db, det, sigma_rad=sigma)
    assert np.array_equal(got.detection_index, np.arange(10))
    # the same blob at a star's noise (1 arcsec) is paired: it was the chance, not the place
    sigma[11] = 1.0 * ARCSEC
    got = rematched(_ident(range(10), range(10), db), db, det, sigma_rad=sigma)
    assert np.array_equal(got.detection_index, np.r_[np.arange(10), 11])


def test_a_star_already_matched_is_not_given_a_second_detection():
    rng = np.random.default_rng(7)
    stars = _sky(8, rng)
    db = _db(stars)
    sigma = np.full(9, 2.0 * ARCSEC)
    # detection 8: a piece of star 7's image, 1 sigma from it; star 7 is matched to detection 7
    det = np.vstack([stars, _offset(stars[7], 2.0 * ARCSEC, rng)])
    got = rematched(_ident(range(8), range(8), db), db, det, sigma_rad=sigma)
    assert np.array_equal(got.detection_index, np.arange(8))
