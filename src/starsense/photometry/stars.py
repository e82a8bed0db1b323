"""Catalogue stars as black bodies: what the physical limit needs of each star.

Every star of a :class:`~starsense.catalog.Catalog` is reduced to its unit vector, the
equivalent black body (temperature T and dilution C, Fialho & Mortari 2019, eqs. 1, 9) fitted to
its colour and magnitude, and the magnitude that ranks it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from starsense.errors import InputError
from starsense.photometry.blackbody import FISHER_CONSTANT
from starsense.photometry.colour import COLOUR_SYSTEMS, ColourModel

__all__ = ["BlackBodyStars", "b_v_from_spectral_type"]


@dataclass(frozen=True, eq=False)
class BlackBodyStars:
    """Catalogue stars reduced to what the limit needs.

    Attributes
    ----------
    vectors : array (N, 3)
        ICRS unit vectors.
    temperature_k, dilution : array (N,)
        Equivalent black body of each star (eqs. 1, 9).
    magnitude : array (N,)
        The catalogue magnitude that ranks the stars (N brightest).
    colour : str
        The colour system the black bodies were fitted in.
    n_skipped : int
        Catalogue stars left out for lack of a finite magnitude or colour.
    """

    vectors: np.ndarray = field(repr=False)
    temperature_k: np.ndarray = field(repr=False)
    dilution: np.ndarray = field(repr=False)
    magnitude: np.ndarray = field(repr=False)
    colour: str = "B-V"
    n_skipped: int = 0

    def __len__(self) -> int:
        return len(self.dilution)

    @property
    def fisher_unit(self) -> np.ndarray:
        """F_i for D = 1 m, t = 1 s; scale by D^4 t for any other sensor (eq. 19)."""
        return FISHER_CONSTANT * self.dilution * self.temperature_k**5

    def subset(self, index) -> BlackBodyStars:
        """Return the stars selected by ``index`` (mask or indices), same colour and skips."""
        return BlackBodyStars(
            self.vectors[index],
            self.temperature_k[index],
            self.dilution[index],
            self.magnitude[index],
            self.colour,
            self.n_skipped,
        )

    @classmethod
    def from_catalog(cls, catalog, colour: str | None = None) -> BlackBodyStars:
        """Fit every star of a :class:`~starsense.catalog.Catalog` with a black body.

        ``colour`` picks the colour system (default: the first of B-V, BT-VT, J-H, H-Ks, J-Ks,
        V-I, BP-RP that the catalogue has). A catalogue with a magnitude but no colour (BSC5)
        uses B-V from the spectral type (:func:`b_v_from_spectral_type`) when it has one.
        Stars without a finite magnitude or colour are skipped and counted in ``n_skipped``.
        """
        mags, colours = dict(catalog.mags), dict(catalog.colours)
        if "B-V" not in colours and "spectral_type" in getattr(catalog, "extra", {}):
            colours["B-V"] = b_v_from_spectral_type(catalog.extra["spectral_type"])
        available = [c for c in COLOUR_SYSTEMS if c in colours and COLOUR_SYSTEMS[c][2] in mags]
        if colour is None:
            order = ["B-V", "BT-VT", "J-H", "H-Ks", "J-Ks", "V-I", "BP-RP"]
            colour = next((c for c in order if c in available), None)
            if colour is None:
                raise InputError(
                    f"catalogue {catalog.name!r} has no colour index usable for the black-body "
                    f"model (has colours {sorted(colours)} and magnitudes {sorted(mags)})"
                )
        elif colour not in available:
            raise InputError(
                f"catalogue {catalog.name!r} cannot provide colour system {colour!r}; "
                f"available: {', '.join(available) or 'none'}"
            )
        model = ColourModel(colour)
        mag = np.asarray(mags[model.magnitude_band], dtype=float)
        ci = np.asarray(colours[colour], dtype=float)
        ok = np.isfinite(mag) & np.isfinite(ci)
        t, c = model.fit(mag[ok], ci[ok])
        return cls(
            vectors=np.asarray(catalog.vectors)[ok],
            temperature_k=t,
            dilution=c,
            magnitude=mag[ok],
            colour=colour,
            n_skipped=int((~ok).sum()),
        )


# Intrinsic B-V of main-sequence stars by spectral class (Schmidt-Kaler 1982, in Landolt-
# Boernstein VI/2b, as tabulated in Allen's Astrophysical Quantities, 4th ed., Table 15.7).
# Luminosity class and reddening are ignored: a rough colour for catalogues (BSC5) that give only
# a two-character spectral type.
_SPECTRAL_B_V = {
    "O": [(5, -0.33), (9, -0.31)],
    "B": [(0, -0.30), (2, -0.24), (5, -0.17), (8, -0.11)],
    "A": [(0, -0.02), (2, 0.05), (5, 0.15), (7, 0.20)],
    "F": [(0, 0.30), (2, 0.35), (5, 0.44), (8, 0.52)],
    "G": [(0, 0.58), (2, 0.63), (5, 0.68), (8, 0.74)],
    "K": [(0, 0.81), (2, 0.91), (5, 1.15), (7, 1.33)],
    "M": [(0, 1.40), (2, 1.49), (5, 1.64), (8, 1.80)],
}


def b_v_from_spectral_type(types) -> np.ndarray:
    """Approximate B-V from spectral types such as "A0", "K5", "B" (NaN when unknown)."""
    out = np.full(len(types), np.nan)
    for i, s in enumerate(types):
        s = str(s).strip().upper()
        if not s or s[0] not in _SPECTRAL_B_V:
            continue
        table = _SPECTRAL_B_V[s[0]]
        sub = int(s[1]) if len(s) > 1 and s[1].isdigit() else 5
        xs = [p[0] for p in table]
        ys = [p[1] for p in table]
        out[i] = np.interp(sub, xs, ys)
    return out
