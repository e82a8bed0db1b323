"""The :class:`Catalog` type: an immutable, columnar star catalogue.

A catalogue is one object holding ``(N,)`` arrays (positions, magnitudes, colours, proper
motions, ...), never a list of star objects. Positions are ICRS, in radians, at the Julian
epoch ``epoch_yr``; magnitudes and colours are in named columns (NaN where missing).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import operator
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from starsense._validate import finite_float
from starsense.catalog import index as _index
from starsense.catalog._columns import (
    check_magnitudes,
    extra_columns,
    float_column,
    id_column,
    named_columns,
    position_columns,
    readonly,
)
from starsense.catalog.propagate import propagate_columns
from starsense.errors import InputError
from starsense.geometry.projection import radec_to_vectors
from starsense.units import DEG, MAS

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

KNOWN_BANDS: tuple[str, ...] = ("V", "B", "I", "Hp", "BT", "VT", "J", "H", "Ks", "G", "BP", "RP")
"""Allowed magnitude column names: Johnson V, B; Cousins I; Hipparcos Hp; Tycho BT, VT;
2MASS J, H, Ks; Gaia G, BP, RP."""

KNOWN_COLOURS: tuple[str, ...] = ("B-V", "V-I", "BT-VT", "J-H", "J-Ks", "H-Ks", "BP-RP")
"""Allowed colour-index column names."""


@dataclass(frozen=True, eq=False, repr=False, kw_only=True)
class Catalog:
    """An immutable, columnar star catalogue (ICRS positions at one epoch).

    Parameters
    ----------
    name : str
        Short name, e.g. ``"hip2"``.
    source : str
        Where the data came from (file path or description).
    epoch_yr : float
        Julian epoch of the positions, years (e.g. 1991.25 for Hipparcos, 2000.0 for BSC5,
        Tycho-2 and 2MASS, 2016.0 for Gaia DR3).
    ids : array_like of int, shape (N,)
        Catalogue identifiers as int64 (HIP, HR, packed TYC, 2MASS ``pts_key``, Gaia
        ``source_id``; each reader documents its choice).
    ra_rad, dec_rad : array_like of float, shape (N,)
        ICRS right ascension and declination, radians. Must be finite; RA is wrapped into
        ``[0, 2 pi)`` and ``|dec| <= pi / 2`` is required.
    mags : mapping of str to array_like, shape (N,)
        Magnitude columns keyed by band, names from :data:`KNOWN_BANDS`. Missing values NaN.
    colours : mapping of str to array_like, shape (N,)
        Colour-index columns, names from :data:`KNOWN_COLOURS`. Missing values NaN.
    pm_ra_rad_yr : array_like, shape (N,), optional
        Proper motion in RA times cos(Dec), ``mu_alpha* = d(alpha)/dt cos(delta)``,
        radians per Julian year. NaN where unknown (such stars are not moved by
        :meth:`propagate`).
    pm_dec_rad_yr : array_like, shape (N,), optional
        Proper motion in declination, radians per Julian year. Given together with
        ``pm_ra_rad_yr``.
    parallax_rad : array_like, shape (N,), optional
        Trigonometric parallax, radians.
    extra : mapping of str to ndarray, shape (N, ...)
        Anything else (e.g. ``"spectral_type"`` as a str array). Object arrays are refused.
    radial_motion_per_yr : array_like, shape (N,), optional
        "Radial proper motion" ``mu_r = v_r / d`` (radial velocity over distance), per Julian
        year (ESA 1997, Vol. 1, Sect. 1.5.5, where ``mu_r = v_r * parallax / A``). None means
        zero. :meth:`propagate` fills it: a star moving uniformly on a straight line acquires
        a radial motion relative to the new line of sight, and carrying it makes
        propagation exactly reversible.

    Notes
    -----
    Columns are stored as read-only views (no copy is made of float64 input). Identity, not
    value, equality applies (``eq=False``); compare columns with NumPy. Build one with
    :func:`starsense.catalog.load_catalog` (a file or the bundled Hipparcos) or with keywords
    (every field is keyword-only).
    """

    name: str
    source: str
    epoch_yr: float
    ids: np.ndarray
    ra_rad: np.ndarray
    dec_rad: np.ndarray
    mags: Mapping[str, np.ndarray] = field(default_factory=dict)
    colours: Mapping[str, np.ndarray] = field(default_factory=dict)
    pm_ra_rad_yr: np.ndarray | None = None
    pm_dec_rad_yr: np.ndarray | None = None
    parallax_rad: np.ndarray | None = None
    extra: Mapping[str, np.ndarray] = field(default_factory=dict)
    radial_motion_per_yr: np.ndarray | None = None

    # -- construction & validation -------------------------------------------------------
    def __post_init__(self) -> None:
        def put(attr: str, value: object) -> None:
            object.__setattr__(self, attr, value)

        if not isinstance(self.name, str) or not self.name:
            raise InputError(f"name must be a non-empty string, got {self.name!r}")
        put("source", str(self.source))
        put("epoch_yr", finite_float(self.epoch_yr, "epoch_yr"))

        ra = float_column("ra_rad", self.ra_rad, None)
        n = ra.shape[0]
        dec = float_column("dec_rad", self.dec_rad, n)
        ids = id_column(self.ids, n)
        ra, dec = position_columns(ra, dec, ids)
        put("ra_rad", ra)
        put("dec_rad", dec)
        put("ids", ids)

        put("mags", named_columns("mags", self.mags, KNOWN_BANDS, n))
        check_magnitudes(self.mags, ids, self.source)
        put("colours", named_columns("colours", self.colours, KNOWN_COLOURS, n))

        if (self.pm_ra_rad_yr is None) != (self.pm_dec_rad_yr is None):
            raise InputError("give both pm_ra_rad_yr and pm_dec_rad_yr, or neither")
        for attr in ("pm_ra_rad_yr", "pm_dec_rad_yr", "parallax_rad", "radial_motion_per_yr"):
            value = getattr(self, attr)
            if value is not None:
                put(attr, float_column(attr, value, n))
        put("extra", extra_columns(self.extra, n))

    @classmethod
    def from_columns(
        cls,
        *,
        name: str,
        source: str,
        epoch_yr: float,
        ids: object,
        ra_deg: object,
        dec_deg: object,
        mags: Mapping[str, object] | None = None,
        colours: Mapping[str, object] | None = None,
        pm_ra_mas_yr: object | None = None,
        pm_dec_mas_yr: object | None = None,
        parallax_mas: object | None = None,
        extra: Mapping[str, object] | None = None,
    ) -> Catalog:
        """Build a catalogue from columns in the units catalogues are published in.

        Parameters
        ----------
        ra_deg, dec_deg : array_like, shape (N,)
            ICRS position, degrees.
        pm_ra_mas_yr, pm_dec_mas_yr : array_like, shape (N,), optional
            Proper motion ``mu_alpha*`` (including cos Dec) and ``mu_delta``, mas per year.
        parallax_mas : array_like, shape (N,), optional
            Parallax, milliarcseconds.
        name, source, epoch_yr, ids, mags, colours, extra
            As for :class:`Catalog`.
        """

        def scaled(values: object | None, factor: float) -> np.ndarray | None:
            return None if values is None else np.asarray(values, dtype=np.float64) * factor

        return cls(
            name=name,
            source=source,
            epoch_yr=epoch_yr,
            ids=ids,
            ra_rad=scaled(ra_deg, DEG),
            dec_rad=scaled(dec_deg, DEG),
            mags=dict(mags or {}),
            colours=dict(colours or {}),
            pm_ra_rad_yr=scaled(pm_ra_mas_yr, MAS),
            pm_dec_rad_yr=scaled(pm_dec_mas_yr, MAS),
            parallax_rad=scaled(parallax_mas, MAS),
            extra=dict(extra or {}),
        )

    # -- basic protocol ------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self.ra_rad.shape[0])

    def __repr__(self) -> str:
        return (
            f"Catalog(name={self.name!r}, n_stars={len(self)}, epoch_yr={self.epoch_yr}, "
            f"mags={list(self.mags)}, colours={list(self.colours)}, "
            f"proper_motion={self.pm_ra_rad_yr is not None}, source={self.source!r})"
        )

    @property
    def bands(self) -> tuple[str, ...]:
        """Names of the magnitude columns."""
        return tuple(self.mags)

    @cached_property
    def vectors(self) -> np.ndarray:
        """ICRS unit vectors, shape (N, 3), read-only."""
        return readonly(radec_to_vectors(self.ra_rad, self.dec_rad))

    @cached_property
    def _tree(self) -> cKDTree:
        return _index.build_tree(self.vectors)

    @cached_property
    def _id_order(self) -> np.ndarray:
        return np.argsort(self.ids, kind="stable")

    # -- selection -----------------------------------------------------------------------
    def subset(self, index_or_mask: object) -> Catalog:
        """Return the stars selected by a boolean mask, an integer index array or a slice.

        Every column is sliced consistently (same name, source and epoch); a mask has shape
        ``(N,)``.
        """
        idx = self._normalise_index(index_or_mask)

        def take(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[idx]

        new = Catalog(
            name=self.name,
            source=self.source,
            epoch_yr=self.epoch_yr,
            ids=self.ids[idx],
            ra_rad=self.ra_rad[idx],
            dec_rad=self.dec_rad[idx],
            mags={k: v[idx] for k, v in self.mags.items()},
            colours={k: v[idx] for k, v in self.colours.items()},
            pm_ra_rad_yr=take(self.pm_ra_rad_yr),
            pm_dec_rad_yr=take(self.pm_dec_rad_yr),
            parallax_rad=take(self.parallax_rad),
            extra={k: v[idx] for k, v in self.extra.items()},
            radial_motion_per_yr=take(self.radial_motion_per_yr),
        )
        if "vectors" in self.__dict__:  # reuse computed unit vectors
            new.__dict__["vectors"] = readonly(self.vectors[idx])
        return new

    def _normalise_index(self, index_or_mask: object) -> slice | np.ndarray:
        if isinstance(index_or_mask, slice):
            return index_or_mask
        idx = np.asarray(index_or_mask)
        n = len(self)
        if idx.dtype == bool:
            if idx.shape != (n,):
                raise InputError(f"boolean mask must have shape ({n},), got {idx.shape}")
            return idx
        if idx.size == 0:
            return idx.astype(np.int64).reshape(0)
        if not np.issubdtype(idx.dtype, np.integer) or idx.ndim != 1:
            raise InputError(
                "index must be a boolean mask (N,), a 1-D integer array or a slice; "
                f"got dtype {idx.dtype}, shape {idx.shape}"
            )
        out = (idx < -n) | (idx >= n)
        if out.any():
            raise InputError(f"index {int(idx[np.argmax(out)])} out of range for {n} stars")
        return idx

    def _mag(self, band: str) -> np.ndarray:
        if band not in self.mags:
            available = ", ".join(self.mags) or "none"
            raise InputError(
                f"band {band!r} not in catalogue {self.name!r}; available bands: {available}"
            )
        return self.mags[band]

    def _sort_order(self, band: str) -> np.ndarray:
        # Stable argsort puts NaN last; ties keep catalogue order.
        return np.argsort(self._mag(band), kind="stable")

    def brighter_than(self, band: str, max_mag: float) -> Catalog:
        """Stars with ``mags[band] <= max_mag`` (stars without a magnitude are excluded).

        Parameters
        ----------
        band : str
            A magnitude column of this catalogue.
        max_mag : float
            Faint limit, magnitudes (inclusive). ``inf`` keeps every star with a magnitude.
        """
        mag = self._mag(band)
        if isinstance(max_mag, bool) or not isinstance(max_mag, numbers.Real):
            raise InputError(f"max_mag must be a number, got {max_mag!r}")
        if math.isnan(max_mag):
            raise InputError("max_mag must not be NaN")
        return self.subset(mag <= max_mag)

    def brightest(self, n: int, band: str) -> Catalog:
        """Return the ``n`` brightest stars in ``band``, sorted brightest first.

        Fewer if fewer stars have a magnitude in that band.
        """
        try:
            count = operator.index(n)
        except TypeError:
            raise InputError(f"n must be an integer, got {n!r}") from None
        if isinstance(n, bool) or count < 0:
            raise InputError(f"n must be a non-negative integer, got {n!r}")
        order = self._sort_order(band)
        n_with_mag = int(np.isfinite(self.mags[band]).sum())
        return self.subset(order[: min(count, n_with_mag)])

    def sorted_by(self, band: str) -> Catalog:
        """Return all stars sorted by ``mags[band]``, brightest first.

        Stars without a magnitude in that band come last, in catalogue order.
        """
        return self.subset(self._sort_order(band))

    def index_of(self, ids: object) -> np.ndarray | int:
        """Row index of each identifier (first occurrence); a scalar gives an int.

        Raises
        ------
        InputError
            If an identifier is not in the catalogue.
        """
        q = np.asarray(ids)
        if q.size and not np.issubdtype(q.dtype, np.integer):
            raise InputError(f"ids must be integers, got {ids!r}")
        flat = np.atleast_1d(q.astype(np.int64)).ravel()
        order = self._id_order
        sorted_ids = self.ids[order]
        pos = np.searchsorted(sorted_ids, flat)
        found = pos < len(self)
        found[found] = sorted_ids[pos[found]] == flat[found]
        if not found.all():
            missing = flat[~found][:10].tolist()
            raise InputError(f"ids not in catalogue {self.name!r}: {missing}")
        result = order[pos]
        return int(result[0]) if q.ndim == 0 else result.reshape(q.shape)

    # -- cone queries --------------------------------------------------------------------
    def cone(self, center: object, radius_rad: float) -> np.ndarray:
        """Return the indices (ascending int64) of the stars within ``radius_rad`` of ``center``.

        Parameters
        ----------
        center : array_like, shape (3,) or (2,)
            A unit vector (ICRS) or ``(RA, Dec)`` in radians.
        radius_rad : float
            Cone half-angle, radians (>= 0; values above pi mean the whole sphere).

        Notes
        -----
        Uses a k-d tree over :attr:`vectors` (built on first use and cached), with the chord
        distance ``2 sin(r / 2)``.
        """
        return _index.cone_query(self._tree, center, radius_rad)

    def cones(self, centers: object, radius_rad: object) -> list[np.ndarray]:
        """Return the indices within each of M cones (batched ``query_ball_point``).

        Parameters
        ----------
        centers : array_like, shape (M, 3) or (M, 2)
            Unit vectors or ``(RA, Dec)`` pairs in radians.
        radius_rad : float or array_like, shape (M,)
            Cone half-angles, radians.

        Returns
        -------
        list of numpy.ndarray
            M ascending int64 index arrays.
        """
        return _index.cones_query(self._tree, centers, radius_rad)

    def count_in_cones(self, centers: object, radius_rad: object) -> np.ndarray:
        """Count the stars in each of M cones, ``(M,)`` int64 (arguments as :meth:`cones`)."""
        return _index.count_cones(self._tree, centers, radius_rad)

    # -- epoch propagation ---------------------------------------------------------------
    def propagate(self, epoch_yr: float) -> Catalog:
        """Return the catalogue with positions moved to another Julian epoch.

        Each star moves uniformly on a straight line in space (ESA 1997, *The Hipparcos and
        Tycho Catalogues*, Vol. 1, Sect. 1.5.5, "rigorous" propagation; the kernel and its
        equations are in :mod:`starsense.catalog.propagate`). The proper motions, the radial
        motion and the parallax are carried to the new epoch, which makes the operation
        exactly reversible.

        Parameters
        ----------
        epoch_yr : float
            Target Julian epoch, years.

        Returns
        -------
        Catalog
            A new catalogue at ``epoch_yr`` (``self`` if the epoch is unchanged).

        Raises
        ------
        InputError
            If the catalogue has no proper motions and ``epoch_yr`` differs from its epoch.

        Notes
        -----
        Radial velocities are taken as zero unless ``radial_motion_per_yr`` is given (the
        published catalogues read here carry none, Gaia DR3 excepted); the neglected
        perspective acceleration is below 0.02 arcsec over a decade even for Barnard's star.
        Stars whose proper motion is NaN keep their position.
        """
        epoch = finite_float(epoch_yr, "epoch_yr")
        dt = epoch - self.epoch_yr
        if dt == 0.0:
            return self
        if self.pm_ra_rad_yr is None or self.pm_dec_rad_yr is None:
            raise InputError(
                f"catalogue {self.name!r} has no proper motions: cannot propagate its "
                f"positions from epoch {self.epoch_yr} to {epoch}"
            )
        moved = propagate_columns(
            self.ra_rad,
            self.dec_rad,
            pm_ra_rad_yr=self.pm_ra_rad_yr,
            pm_dec_rad_yr=self.pm_dec_rad_yr,
            radial_motion_per_yr=self.radial_motion_per_yr,
            parallax_rad=self.parallax_rad,
            dt_yr=dt,
            vectors=self.vectors,
        )
        return dataclasses.replace(
            self,
            epoch_yr=epoch,
            **moved,
            mags=dict(self.mags),
            colours=dict(self.colours),
            extra=dict(self.extra),
        )
