"""Seeded lost-in-space centroid sets from a catalogue: the identification benchmark's inputs.

Each set is what a pinhole camera would measure at a random attitude: the pixel positions of
the brightest catalogue stars in the frame, with Gaussian centroid noise, some true stars
dropped (missed by the detector) and false stars (hot pixels, debris, planets) inserted at
random positions and random brightness ranks. Every set carries its truth (attitude, which
detections are true and which catalogue star each is), so a solver can be scored on it.

The boresights are a Fibonacci lattice (:func:`~starsense.geometry.sampling.fibonacci_sphere`),
the rolls uniform; everything random comes from one ``seed``, so a set is reproducible bit for
bit. Pixel convention: (0, 0) is the centre of the top-left pixel, x along columns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from starsense._validate import check_int, check_scalar
from starsense.catalog.table import Catalog
from starsense.errors import InputError
from starsense.geometry.attitude import attitude_from_radec_roll
from starsense.geometry.projection import vectors_to_radec
from starsense.geometry.sampling import fibonacci_sphere
from starsense.units import DEG

__all__ = ["CentroidSets", "centroid_sets"]


@dataclass(frozen=True)
class CentroidSets:
    """Centroid sets with their truth (ragged arrays: set ``i`` is ``xy[offsets[i]:offsets[i+1]]``).

    Attributes
    ----------
    xy : ndarray, shape (M, 2)
        Centroids (x = column, y = row), pixels, pixel-centre convention; brightest first
        within each set.
    offsets : ndarray of int, shape (S + 1,)
        Start of each set in `xy`.
    catalog_id : ndarray of int64, shape (M,)
        Catalogue identifier of each centroid; -1 for a false star.
    boresights : ndarray, shape (S, 3)
        True boresight of each set, ICRS unit vectors.
    rotations : Rotation
        True attitudes (ICRS -> camera), S of them.
    image_size : (int, int)
        Rows, columns of the detector.
    fov_rad : float
        Horizontal field across the image width, rad.
    """

    xy: NDArray[np.float64]
    offsets: NDArray[np.int64]
    catalog_id: NDArray[np.int64]
    boresights: NDArray[np.float64]
    rotations: Rotation
    image_size: tuple[int, int]
    fov_rad: float

    def __len__(self) -> int:
        return len(self.offsets) - 1

    def __getitem__(self, i: int) -> NDArray[np.float64]:
        """Return the centroids (x, y) of set `i`, shape (N, 2)."""
        return self.xy[self.offsets[i] : self.offsets[i + 1]]


def centroid_sets(
    catalog: Catalog,
    n: int,
    *,
    fov_rad: float = 15.0 * DEG,
    image_size: tuple[int, int] = (960, 1280),
    n_stars: int = 20,
    noise_px: float = 0.3,
    n_false: int = 2,
    drop_fraction: float = 0.0,
    mag_limit: float = 9.0,
    band: str = "V",
    seed: int = 20240605,
) -> CentroidSets:
    """Generate `n` seeded lost-in-space centroid sets.

    Per set: the `n_stars` brightest catalogue stars (``band <= mag_limit``) that fall on the
    detector, ``round(drop_fraction * n_stars)`` of them dropped at random, each displaced by
    Gaussian noise of `noise_px` per axis, then `n_false` false stars inserted at uniform random
    positions and random ranks in the brightness order.

    Parameters
    ----------
    catalog : Catalog
        Source catalogue (e.g. the bundled Hipparcos).
    n : int
        Number of sets (Fibonacci boresights).
    fov_rad : float
        Horizontal field across the image width (pinhole), rad.
    image_size : (int, int)
        Rows, columns of the detector, pixels.
    n_stars : int
        Brightest true stars in the frame before dropping.
    noise_px : float
        Centroid noise, pixels, 1 sigma per axis.
    n_false : int
        False stars per set.
    drop_fraction : float
        Fraction of the `n_stars` true stars removed, in [0, 1).
    mag_limit : float
        Faintest magnitude used, in `band`.
    band : str
        Magnitude band for brightness order.
    seed : int
        Root seed.

    Returns
    -------
    CentroidSets

    Raises
    ------
    InputError
        A parameter is out of range, or the catalogue lacks `band`.
    """
    n = check_int(n, "n", 1)
    n_stars = check_int(n_stars, "n_stars", 1)
    n_false = check_int(n_false, "n_false", 0)
    check_scalar(fov_rad, "fov_rad", 0.1 * DEG, 120 * DEG)
    check_scalar(noise_px, "noise_px", 0.0, 100.0)
    check_scalar(drop_fraction, "drop_fraction", 0.0, 1.0, hi_open=True)
    if band not in catalog.mags:
        raise InputError(f"catalogue {catalog.name!r} has no {band!r} magnitudes")
    rows, cols = (int(v) for v in image_size)
    mags = np.asarray(catalog.mags[band], dtype=float)
    ok = np.flatnonzero(np.isfinite(mags) & (mags <= mag_limit))
    ok = ok[np.argsort(mags[ok], kind="stable")]  # brightest first
    stars = catalog.vectors[ok]
    ids = np.asarray(catalog.ids)[ok].astype(np.int64)
    f_px = cols / 2.0 / math.tan(fov_rad / 2.0)
    cx, cy = (cols - 1) / 2.0, (rows - 1) / 2.0
    half_diag = math.atan(math.hypot(cols, rows) / 2.0 / f_px)
    rng = np.random.default_rng(seed)
    bores = fibonacci_sphere(n)
    ra, dec = vectors_to_radec(bores)
    truth = attitude_from_radec_roll(ra, dec, rng.uniform(0.0, 2.0 * math.pi, n))
    tree = cKDTree(stars)
    n_drop = round(drop_fraction * n_stars)
    near_all = tree.query_ball_point(bores, 2.0 * math.sin(min(half_diag + 0.01, math.pi) / 2))
    xy, cid, offsets = [], [], [0]
    for i, near in enumerate(near_all):
        near = np.sort(np.asarray(near, dtype=np.int64))  # brightness order
        cam = truth[i].apply(stars[near])
        front = cam[:, 2] > 0
        near, cam = near[front], cam[front]
        x = cx + f_px * cam[:, 0] / cam[:, 2]
        y = cy + f_px * cam[:, 1] / cam[:, 2]
        inside = np.flatnonzero((x >= 0) & (x <= cols - 1) & (y >= 0) & (y <= rows - 1))
        inside = inside[:n_stars]
        if n_drop:
            gone = rng.choice(len(inside), size=min(n_drop, len(inside)), replace=False)
            inside = np.delete(inside, gone)
        xs = x[inside] + rng.normal(0.0, noise_px, len(inside))
        ys = y[inside] + rng.normal(0.0, noise_px, len(inside))
        cs = ids[near[inside]]
        for _ in range(n_false):
            pos = int(rng.integers(0, len(xs) + 1))
            xs = np.insert(xs, pos, rng.uniform(0, cols - 1))
            ys = np.insert(ys, pos, rng.uniform(0, rows - 1))
            cs = np.insert(cs, pos, -1)
        xy.append(np.column_stack([xs, ys]))
        cid.append(cs)
        offsets.append(offsets[-1] + len(xs))
    return CentroidSets(
        xy=np.concatenate(xy),
        offsets=np.asarray(offsets, dtype=np.int64),
        catalog_id=np.concatenate(cid).astype(np.int64),
        boresights=bores,
        rotations=truth,
        image_size=(rows, cols),
        fov_rad=float(fov_rad),
    )
