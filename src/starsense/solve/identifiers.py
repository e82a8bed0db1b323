"""The identifiers of a Solver: one per known field or field range, of one catalogue, built once.

A known field gets a database of its own size; an unknown one is searched through the ranges of
:func:`starsense.identify.fields.unknown_field_plan`, each with its database, until one solves.
The catalogue is loaded once (when given as a spec) and carried to every database and range.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from starsense.catalog import load_catalog
from starsense.catalog.table import Catalog
from starsense.geometry.distortion import undistort
from starsense.geometry.projection import tangent_to_vectors, vectors_to_tangent
from starsense.identify import Identification, identify_ranked
from starsense.identify.fields import FieldRange, identifier_for, unknown_field_plan
from starsense.identify.verify import apply_scale
from starsense.photometry.colour import magnitudes_in
from starsense.solve.near_miss import is_near_miss, near_miss

#: radial distortions (k1, tangent-plane units of each range's nominal focal length) tried for a
#: frame of unknown optics that does not solve as a pinhole: a third and two thirds of the
#: equidistant (f-theta) lens's k1 = -1/3, the barrel of short wide-angle lenses
DISTORTION_GUESSES = (-1.0 / 9.0, -2.0 / 9.0)
#: near misses of a failed search checked against the frame, best first (each costs a search
#: of its attempt again and a read of the frame; a Bonferroni factor each)
NEAR_MISSES_CHECKED = 2

__all__ = ["FieldIdentifiers", "SkyStars"]


class SkyStars(NamedTuple):
    """Every star of a catalogue with a magnitude in one band (the model fit's sky).

    Attributes
    ----------
    vectors : ndarray (N, 3)
        Catalogue places, ICRS.
    mags : ndarray (N,)
        Magnitudes in the band.
    tree : scipy.spatial.cKDTree
        Over ``vectors``.
    rows : ndarray (N,) of int
        Their rows in ``catalog`` (for their apparent places).
    catalog : Catalog
    """

    vectors: np.ndarray
    mags: np.ndarray
    tree: cKDTree
    rows: np.ndarray
    catalog: Catalog


#: what an identification that the spent budget leaves no pattern to look up returns
_SPENT = Identification("timeout", "hashing")


class FieldIdentifiers:
    """Configure, then ask: ``FieldIdentifiers(catalog, algorithm=...)(fov_rad)``.

    Parameters
    ----------
    catalog : Catalog or str
        The catalogue, or its spec (:func:`starsense.catalog.load_catalog`, loaded when first
        needed). With the spec ``"hipparcos"`` the narrow range of an unknown field uses the
        bundled Gaia when installed; a Catalog object is used for every range.
    algorithm : {"hashing", "triangle"}
        Identification algorithm.
    max_patterns : int, optional
        The work budget of one solve (hashing): the 4-star patterns looked up by all the
        identifications between two calls of :meth:`start`, after which they stop with status
        "timeout" (deterministic: counted in patterns, not time). None: no bound.
    """

    def __init__(
        self, catalog: Catalog | str, *, algorithm: str, max_patterns: int | None = None
    ) -> None:
        self.spec = catalog
        self.algorithm = algorithm
        self.max_patterns = max_patterns
        self._catalog: Catalog | None = catalog if isinstance(catalog, Catalog) else None
        self._plan: list[FieldRange] | None = None
        self._built: dict = {}
        self._skies: dict = {}
        self._spent = 0  # patterns looked up since start()
        self._first: tuple | None = None  # a failed first attempt handed over (keep_first)
        self._evidence = None  # the frame a near miss is checked against (identify's)
        self._near: list = []  # the near misses of the current identify, and their k1 guess
        self._k1 = 0.0  # the distortion guess of the attempt under way
        self._near_tests = [0]  # near-miss tests made in the solve (starsense.solve.near_miss)

    def start(self) -> None:
        """Begin a solve: its identifications share a fresh budget of ``max_patterns``."""
        self._spent = 0
        self._first = None
        self._near_tests = [0]

    def keep_first(self, identifier, vectors, flux, *, fov_rad: float) -> Identification:
        """Identify at a known field; an answer that did not solve is kept for :meth:`identify`.

        The first attempt of a solve made ahead of it (:mod:`starsense.solve.centroid_path`):
        when :meth:`identify` is then asked the same (this identifier, the same vectors,
        brightness and field) it takes this answer instead of identifying again.
        """
        ident = self._ranked(identifier, vectors, flux, fov_rad)
        if not ident.solved:
            key = (identifier, np.asarray(vectors).tobytes(), np.asarray(flux).tobytes(), fov_rad)
            self._first = (key, ident)
        return ident

    def _handed_over(self, identifier, vectors, flux, fov_rad: float) -> Identification | None:
        """Return the answer :meth:`keep_first` kept for exactly this attempt (once), or None."""
        first, self._first = self._first, None
        if first is None:
            return None
        key = (identifier, np.asarray(vectors).tobytes(), np.asarray(flux).tobytes(), fov_rad)
        same = first[0][0] is key[0] and first[0][1:] == key[1:]
        return first[1] if same else None

    def _ranked(self, identifier, vectors, flux, *args, **kwargs) -> Identification:
        """:func:`identify_ranked` within what is left of the solve's budget (hashing).

        A near miss is kept, to be checked against the frame's fainter stars when a frame was
        given to :meth:`identify` and nothing solves (:meth:`_near_misses`).
        """
        ident = self._budgeted(identifier, vectors, flux, *args, **kwargs)
        if not ident.solved and self._evidence is not None and is_near_miss(ident):
            call = (identifier, vectors, flux, ident, args, kwargs)
            self._near.append((ident.best_false_match_probability, len(self._near), call, self._k1))
        return ident

    def _budgeted(self, identifier, vectors, flux, *args, **kwargs) -> Identification:
        if self.max_patterns is None or self.algorithm != "hashing":
            ident = identify_ranked(identifier, vectors, flux, *args, **kwargs)
            self._spent += ident.n_patterns_tried
            return ident
        left = self.max_patterns - self._spent
        ident = _SPENT  # spent by the attempts before: this one looks up nothing
        if left > 0:
            ident = identify_ranked(identifier, vectors, flux, *args, max_patterns=left, **kwargs)
            self._spent += ident.n_patterns_tried
        if ident.status == "timeout" and self._spent >= self.max_patterns:
            why = (
                f"no match within the work budget of one solve, {self.max_patterns} patterns "
                "(max_patterns), summed over its identification attempts"
            )
            ident = dataclasses.replace(ident, message=why)
        return ident

    @property
    def catalog(self) -> Catalog:
        """The catalogue (a spec is loaded here, once)."""
        if self._catalog is None:
            self._catalog = load_catalog(self.spec)
        return self._catalog

    def sky(self, band: str) -> SkyStars:
        """Return every star of the catalogue with a magnitude in ``band``, built once per band.

        The stars the forward model's fit draws beside the identified ones (their neighbours,
        the stars in view): the whole catalogue, not the identification database, which keeps
        a few stars per field. A star the catalogue gives no magnitude in ``band`` takes one
        from its other bands (:func:`starsense.photometry.colour.magnitudes_in`): a sky of
        Hipparcos stars beside a Gaia database keeps its bright stars.
        """
        if band not in self._skies:
            mags = magnitudes_in(self.catalog, band)
            keep = np.flatnonzero(np.isfinite(mags))
            vectors = np.asarray(self.catalog.vectors)[keep]
            self._skies[band] = SkyStars(vectors, mags[keep], cKDTree(vectors), keep, self.catalog)
        return self._skies[band]

    def plan(self) -> list[FieldRange]:
        """Return the field ranges searched, in order, when the field is not known."""
        if self._plan is None:
            spec = self.spec
            default = isinstance(spec, str) and spec.strip().lower() == "hipparcos"
            self._plan = unknown_field_plan(self.catalog, deep_narrow=default)
        return self._plan

    def __call__(self, fov_rad: float | None = None, field_range: FieldRange | None = None):
        """Return the identifier of a known field or of one range of the unknown-field search.

        Built (or loaded from the disk cache) once per field and kept.

        Parameters
        ----------
        fov_rad : float, optional
            The known field (full width), rad.
        field_range : FieldRange, optional
            A range of :meth:`plan`, when ``fov_rad`` is None (default: its first).

        Returns
        -------
        HashIdentifier or TriangleIdentifier
            Its ``database`` is the identification database.
        """
        if fov_rad is None and field_range is None:
            field_range = self.plan()[0]
        key = (self.algorithm, None if fov_rad is None else round(fov_rad, 9), field_range)
        if key not in self._built:
            self._built[key] = identifier_for(
                self.catalog, algorithm=self.algorithm, fov_rad=fov_rad, field_range=field_range
            )
        return self._built[key]

    def search_distorted(self, vectors: np.ndarray, flux: np.ndarray, fov_assumed_rad: float):
        """Identify an unknown field through a guessed barrel distortion.

        For each guess of :data:`DISTORTION_GUESSES` the vectors are re-unprojected at each
        range's nominal field and undistorted (:mod:`starsense.geometry.distortion`), and
        the common and wide ranges searched (a narrow field is not bent enough to need it).

        Parameters
        ----------
        vectors, flux, fov_assumed_rad
            As :meth:`search`.

        Returns
        -------
        identifier, Identification or None, float
            The last identifier, its answer and the k1 that solved, in tangent-plane units of
            the focal length found (0 when none solved); no answer (None) when no guess
            inverts over the points.
        """
        t = vectors_to_tangent(vectors)
        identifier, ident = None, None
        for k1 in DISTORTION_GUESSES:
            for field_range in self.plan()[:2]:
                identifier = self(None, field_range)
                nominal = field_range.nominal_fov_rad
                u, w = undistort(*(t * (math.tan(nominal / 2) / math.tan(fov_assumed_rad / 2))).T,
                                 (k1, 0.0, 0.0, 0.0))  # fmt: skip
                if not (np.isfinite(u).all() and np.isfinite(w).all()):
                    continue  # a lens's distortion inverts over its own image: not this guess
                v = tangent_to_vectors(np.column_stack([u, w]))
                self._k1 = k1
                ident = self._ranked(identifier, v, flux, None, assumed_fov_rad=nominal)
                self._k1 = 0.0
                if ident.status == "timeout":  # the solve's budget is spent
                    return identifier, ident, 0.0
                if ident.solved:
                    # the tangent found is scale x the one assumed: k1 / scale^2 at the true focus
                    return identifier, ident, k1 / ident.scale**2
        return identifier, ident, 0.0

    def search(self, vectors: np.ndarray, flux: np.ndarray, fov_assumed_rad: float):
        """Identify with the field unknown: each range of the plan in turn until one solves.

        Parameters
        ----------
        vectors : ndarray, shape (N, 3)
            Camera-frame unit vectors, unprojected with the field ``fov_assumed_rad``.
        flux : ndarray, shape (N,)
            Brightness of each (larger is brighter).
        fov_assumed_rad : float
            The field the vectors were unprojected with, rad.

        Returns
        -------
        identifier, Identification
            The last range's identifier and its answer.
        """
        tried, best = 0, 1.0  # over every range tried: the counts of a failed search
        for field_range in self.plan():
            identifier = self(None, field_range)
            nominal = field_range.nominal_fov_rad  # re-unproject at the range's own field
            v = apply_scale(vectors, math.tan(nominal / 2) / math.tan(fov_assumed_rad / 2))
            ident = self._ranked(identifier, v, flux, None, assumed_fov_rad=nominal)
            tried += ident.n_patterns_tried
            best = min(best, ident.best_false_match_probability)
            if ident.solved or ident.status == "timeout":
                break
        return identifier, dataclasses.replace(
            ident, n_patterns_tried=tried, best_false_match_probability=best
        )

    def identify(
        self, vectors, flux, *, fov_known_rad, fov_assumed_rad, estimate: bool, evidence=None
    ) -> tuple[object, Identification, float | None, float]:
        """Return (identifier, identification, known field or None, radial k1 assumed).

        When the field is searched and does not solve as a pinhole, it is searched again
        through guessed barrel distortions (:meth:`search_distorted`); the k1 that solved is
        returned (tangent-plane units of the focal length found; 0 for a pinhole).

        Parameters
        ----------
        vectors : ndarray, shape (N, 3)
            Camera-frame unit vectors.
        flux : ndarray, shape (N,)
            Brightness of each.
        fov_known_rad : float or None
            The known field, rad; None to search the plan.
        fov_assumed_rad : float
            The field the vectors were unprojected with, rad.
        estimate : bool
            The known field is an estimate (no sensor): when it does not solve, the scale is
            searched around it (hashing, 4 vectors or more), which refines the field.
        evidence : FrameEvidence, optional
            The frame behind the vectors: a near miss is checked against its fainter stars
            (:mod:`starsense.solve.near_miss`).
        """
        self._evidence, self._near, self._k1 = evidence, [], 0.0
        try:
            out = self._identify(vectors, flux, fov_known_rad, fov_assumed_rad, estimate)
            if out[1].solved or out[1].status == "timeout" or not self._near:
                return out
            return self._near_misses() or out
        finally:
            self._evidence, self._near = None, []

    def _near_misses(self):
        """Check the best near misses of a search that solved nothing against the frame.

        Checked only once every attempt (every field range, every distortion guess) failed,
        best first, the first :data:`NEAR_MISSES_CHECKED`: a frame that solves the ordinary way
        keeps that way's answer (a distortion guess's camera fit, say).
        """
        for _, _, call, k1 in sorted(self._near, key=lambda c: c[:2])[:NEAR_MISSES_CHECKED]:
            identifier, vectors, flux, ident, args, kwargs = call
            got = near_miss(
                identifier,
                vectors,
                flux,
                ident=ident,
                args=args,
                kwargs=kwargs,
                evidence=self._evidence,
                tests=self._near_tests,
            )
            if got.solved:
                return identifier, got, args[0] if args else None, k1 / got.scale**2
        return None

    def _identify(self, vectors, flux, fov_known_rad, fov_assumed_rad, estimate):
        searched = fov_known_rad is None
        if not searched:
            identifier = self(fov_known_rad)
            ident = self._handed_over(identifier, vectors, flux, fov_known_rad)
            if ident is None:
                ident = self._ranked(identifier, vectors, flux, fov_known_rad)
            searched = (
                not ident.solved
                and ident.status != "timeout"
                and estimate
                and self.algorithm == "hashing"
                and len(vectors) >= 4  # the 4-star patterns need 4; no scale to search with fewer
            )
            if not searched:
                return identifier, ident, fov_known_rad, 0.0
        identifier, ident = self.search(vectors, flux, fov_assumed_rad)
        if ident.solved or not estimate or len(vectors) < 4 or self.algorithm != "hashing":
            return identifier, ident, None, 0.0
        if ident.status == "timeout":  # the budget is spent: no distortion guess
            return identifier, ident, None, 0.0
        found = self.search_distorted(vectors, flux, fov_assumed_rad)
        # else the pinhole search's (also where no guess inverts over the points: None)
        kept = found[1] is not None and (found[1].solved or found[1].status == "timeout")
        return (*found[:2], None, found[2]) if kept else (identifier, ident, None, 0.0)
