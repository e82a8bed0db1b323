"""One-to-one nearest pairs of the lens fit (starsense.solve.pairing.nearest_pairs).

Held against a brute-force greedy pairing written here: every detection looks at its nearest
star (all distances computed), the closest detection-star distances are taken first, and a
star already taken leaves its later detection unpaired.
"""

from __future__ import annotations

import numpy as np
import pytest

from starsense.solve.pairing import nearest_pairs


def _greedy(pred, xy, radius):
    finite = np.isfinite(pred).all(axis=1)
    if not finite.any() or len(xy) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    d = np.linalg.norm(xy[:, None, :] - np.where(finite[:, None], pred, np.inf)[None], axis=2)
    d[:, ~finite] = np.inf
    star = np.argmin(d, axis=1)
    dist = d[np.arange(len(xy)), star]
    taken, pairs = set(), []
    for i in np.argsort(dist, kind="stable"):
        if dist[i] <= radius and star[i] not in taken:
            taken.add(int(star[i]))
            pairs.append((int(i), int(star[i])))
    pairs.sort()
    det = np.array([p[0] for p in pairs], np.int64)
    return det, np.array([p[1] for p in pairs], np.int64)


@pytest.mark.parametrize("seed", range(40))
def test_nearest_pairs_are_the_greedy_pairing(seed):
    rng = np.random.default_rng(seed)
    pred = rng.uniform(0.0, 100.0, (int(rng.integers(1, 60)), 2))
    pred[rng.random(len(pred)) < 0.2] = np.nan  # stars outside the image
    xy = rng.uniform(0.0, 100.0, (int(rng.integers(1, 80)), 2))
    radius = float(rng.uniform(1.0, 20.0))
    det, star = nearest_pairs(pred, xy, radius)
    want_det, want_star = _greedy(pred, xy, radius)
    np.testing.assert_array_equal(det, want_det)
    np.testing.assert_array_equal(star, want_star)
    assert len(np.unique(star)) == len(star)  # one to one


def test_no_star_in_view_gives_no_pair():
    det, star = nearest_pairs(np.full((3, 2), np.nan), np.zeros((2, 2)), 5.0)
    assert len(det) == 0 and len(star) == 0
