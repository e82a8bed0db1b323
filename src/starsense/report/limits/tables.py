"""The numbers of the limit section: Table 2 (FOV-limited heads) and Table 1 (black bodies)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from starsense.analysis.limits.centroid import centroid_fisher
from starsense.analysis.limits.result import LimitResult, limit_from_fisher
from starsense.analysis.limits.sky import fov_fishers, fov_limit, in_cone
from starsense.errors import SingularGeometryError
from starsense.geometry.projection import radec_to_vectors
from starsense.photometry import fit_star
from starsense.photometry.stars import BlackBodyStars
from starsense.references import fialho2019 as paper
from starsense.report.page import fmt
from starsense.units import DEG, RAD_TO_MAS

__all__ = [
    "FovCell",
    "FovRow",
    "Table1Row",
    "fov_table",
    "in_interval",
    "radec_vector",
    "table1_rows",
]


def radec_vector(ra_h: float, dec_deg: float) -> np.ndarray:
    """Return the ICRS unit vector (3,) of (RA in hours, Dec in degrees)."""
    return radec_to_vectors(15.0 * ra_h * DEG, dec_deg * DEG)


def in_interval(g: float, interval=paper.G_INTERVAL) -> bool:
    """Return whether ``g`` lies in the closed ``interval`` (default: the paper's G interval)."""
    return bool(interval[0] <= g <= interval[1])


@dataclass(frozen=True)
class FovCell:
    """One cell of the Table 2 reproduction: a head (or the merged heads) at one FOV.

    ``result`` is None when the stars in view do not determine the attitude (fewer than 2 stars,
    or all along one axis).
    """

    n_stars: int
    result: LimitResult | None

    @property
    def theta_mas(self) -> float | None:
        """theta_rms in mas, or None when singular."""
        return None if self.result is None else self.result.theta_rms_rad * RAD_TO_MAS

    def html(self) -> str:
        """Return the cell's HTML: theta_rms (mas) or "singular (n stars)"."""
        if self.result is None:
            return f"singular ({self.n_stars} star{'s' if self.n_stars != 1 else ''})"
        return fmt(self.theta_mas)

    def to_dict(self) -> dict:
        """Return the JSON form (rad, and mas for the edges)."""
        if self.result is None:
            return {"n_stars": self.n_stars, "singular": True, "theta_rms_mas": None}
        d = self.result.to_dict()
        d["singular"] = False
        d["theta_rms_mas"] = self.theta_mas
        d["axis_sigma_mas"] = [float(x) * RAD_TO_MAS for x in self.result.axis_sigma_rad]
        return d


@dataclass(frozen=True)
class FovRow:
    """One row of Table 2: the heads and the merged heads at one FOV diameter (deg)."""

    fov_deg: float
    heads: tuple[FovCell, ...]
    merged: FovCell


def _merged(stars: BlackBodyStars, targets, fov_rad, diameter_m, exposure_s) -> FovCell:
    """Return the merged heads from the kernels, for when a head alone is singular (eq. 20-22)."""
    fishers, counts = fov_fishers(
        stars, targets, fov_diameter_rad=fov_rad, diameter_m=diameter_m, exposure_s=exposure_s
    )
    n = int(counts.sum())
    try:
        return FovCell(
            n,
            limit_from_fisher(fishers.sum(axis=0), n, diameter_m=diameter_m, exposure_s=exposure_s),
        )
    except SingularGeometryError:
        return FovCell(n, None)


def fov_table(
    stars: BlackBodyStars,
    *,
    diameter_m: float = paper.TABLE2_DIAMETER_M,
    exposure_s: float = paper.TABLE2_EXPOSURE_S,
    fovs_deg=tuple(paper.TABLE2_MAS),
    targets=paper.TABLE2_TARGETS,
) -> list[FovRow]:
    """Compute Table 2: the FOV-limited limit per head and merged (sec. 3.4).

    Heads whose stars do not determine the attitude are kept as singular cells.

    Parameters
    ----------
    stars : BlackBodyStars
        The catalogue's stars.
    diameter_m, exposure_s : float
        D (m) and t (s) of the sensor (the paper's: 10 cm, 10 ms).
    fovs_deg : sequence of float
        FOV diameters, deg (the report's edge unit; converted here).
    targets : sequence of (label, RA in hours, Dec in degrees)
        The heads' pointings.

    Returns
    -------
    list of FovRow
    """
    vecs = np.array([radec_vector(ra, dec) for _, ra, dec in targets])
    rows = []
    for fov in fovs_deg:
        fov_rad = fov * DEG
        try:
            heads, merged = fov_limit(
                stars, vecs, fov_diameter_rad=fov_rad, diameter_m=diameter_m, exposure_s=exposure_s
            )
            cells = tuple(FovCell(h.n_stars, h) for h in heads)
            both = FovCell(merged.n_stars, merged) if merged is not None else None
        except SingularGeometryError:
            cells = []
            for v in vecs:
                try:
                    (h,), _ = fov_limit(
                        stars,
                        v,
                        fov_diameter_rad=fov_rad,
                        diameter_m=diameter_m,
                        exposure_s=exposure_s,
                    )
                    cells.append(FovCell(h.n_stars, h))
                except SingularGeometryError:
                    cells.append(FovCell(int(in_cone(stars.vectors, v, fov_rad).sum()), None))
            cells = tuple(cells)
            both = _merged(stars, vecs, fov_rad, diameter_m, exposure_s)
        rows.append(FovRow(float(fov), cells, both))
    return rows


@dataclass(frozen=True)
class Table1Row:
    """One star of Table 1: our black-body fit and the paper's (T in K, C, sigma in rad)."""

    colour: str
    name: str
    magnitude: float
    colour_index: float
    temperature_k: float
    dilution: float
    sigma_rad: float
    paper: tuple[float, float, float]  # T, C, sigma


def table1_rows() -> list[Table1Row]:
    """Compute Table 1: black-body T, C and centroid bound sigma = F^-1/2 (eq. 19) of five stars.

    Returns
    -------
    list of Table1Row
        The UBV half, then the 2MASS half.
    """
    rows = []
    for colour, ref in (("B-V", paper.TABLE1_UBV), ("H-Ks", paper.TABLE1_HKS)):
        for name, mag, ci, t_ref, c_ref, s_ref in ref:
            t, c = fit_star(mag, ci, colour)
            f = centroid_fisher(
                c, t, diameter_m=paper.TABLE1_DIAMETER_M, exposure_s=paper.TABLE1_EXPOSURE_S
            )
            rows.append(
                Table1Row(colour, name, mag, ci, t, c, float(1 / np.sqrt(f)), (t_ref, c_ref, s_ref))
            )
    return rows
