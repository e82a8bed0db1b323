"""The result type shared by every attitude estimator, input validation, and the common driver.

Wahba's problem (Wahba 1965) with per-star weights: find the attitude ``A`` (ICRS -> camera,
the convention of :mod:`starsense.geometry.attitude`) minimising

    L(A) = 1/2 sum_i w_i |b_i - A r_i|^2,        w_i = sigma_i^-2,

where ``b_i`` are the measured camera-frame unit vectors, ``r_i`` the catalogue (ICRS) unit
vectors and ``sigma_i`` the per-axis angular noise of star ``i``. With this normalisation ``2 L``
at the optimum is approximately chi-square distributed with ``2 N - 3`` degrees of freedom when
the sigmas are right, so the loss is a consistency check as well as an objective.
"""

from __future__ import annotations

import time
from dataclasses import MISSING, dataclass, field, fields, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from starsense.errors import InputError

__all__ = ["AttitudeSolution", "validate_observations", "wahba_residuals"]

#: Relative deviation of an input vector's norm from 1 above which a note is recorded.
UNIT_NORM_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class AttitudeSolution:
    """An attitude estimate and what is needed to judge it.

    Attributes
    ----------
    rotation : Rotation
        The attitude ``A``, ICRS -> camera (``v_cam = A.apply(v_icrs)``). It may be given as
        its matrix, shape (3, 3), orthonormal to rounding (a fit's): the Rotation is then built
        when first read (scipy's constructor is paid only by a caller that reads it);
        :attr:`matrix` reads the matrix either way.
    covariance_rad2 : ndarray, shape (3, 3)
        Covariance of the camera-frame error rotation vector (the quantity returned by
        :func:`starsense.geometry.attitude.small_rotation_angles`), rad^2. For the optimal
        estimators (QUEST, Davenport, SVD) it is the inverse of the Fisher matrix of Fialho &
        Mortari 2019, eq. 21, ``F = sum_i sigma_i^-2 (I - b_i b_i^T)``, with the measured
        camera-frame vectors ``b_i``. For TRIAD it is TRIAD's own covariance (Shuster & Oh 1981),
        which is larger: TRIAD uses only two stars and does not weight them optimally.
    residual_rms_rad : float
        rms over stars of the angle between ``b_i`` and ``A r_i``, rad.
    residuals_rad : ndarray, shape (N,)
        Angle between ``b_i`` and ``A r_i`` for each star, rad.
    method : str
        The algorithm that produced ``rotation``: "triad", "quest", "davenport" or "svd". A QUEST
        call that fell back to the q-method reports "davenport" and says why in ``notes``.
    n_stars : int
        Number of star pairs given (TRIAD uses two of them; see ``notes``).
    loss : float
        Wahba loss ``1/2 sum_i sigma_i^-2 |b_i - A r_i|^2`` (dimensionless). ``2 * loss`` is
        approximately chi-square with ``2 N - 3`` degrees of freedom for correct sigmas.
    notes : tuple of str
        Anything the user should know: inputs renormalised, QUEST's sequential rotation or
        fallback, which stars TRIAD used.
    elapsed_s : float
        Wall-clock time of the call (validation, solution, covariance and residuals), s.
    """

    rotation: Rotation
    covariance_rad2: NDArray[np.float64] = field(repr=False)
    residual_rms_rad: float
    residuals_rad: NDArray[np.float64] = field(repr=False)
    method: str
    n_stars: int
    loss: float
    notes: tuple[str, ...] = ()
    elapsed_s: float = 0.0

    @property
    def matrix(self) -> NDArray[np.float64]:
        """The attitude matrix (3, 3), ICRS -> camera: the one given, or the Rotation's."""
        given = self.__dict__["_matrix"]
        return self.rotation.as_matrix() if given is None else given

    @property
    def sigma_axes_rad(self) -> NDArray[np.float64]:
        """sqrt(diag(covariance)), rad, shape (3,): cross-boresight x, y and roll about z."""
        return np.sqrt(np.diag(self.covariance_rad2))

    @classmethod
    def of_fit(cls, matrix: NDArray[np.float64], **values) -> AttitudeSolution:
        """Return the solution of a fit given as its matrix, every other field by keyword.

        What ``AttitudeSolution(rotation=matrix, **fields)`` stores, without the frozen
        dataclass's per-field ``object.__setattr__`` (a solve of a centroid list makes a few):
        the class has no ``__post_init__`` to skip. The Rotation is built when first read.
        """
        if not _FIELDS.issuperset(values) or "rotation" in values:
            raise TypeError(f"AttitudeSolution.of_fit: unexpected fields {sorted(values)}")
        out = object.__new__(cls)
        out.__dict__.update(_DEFAULTS, _matrix=matrix, _rotation=None, **values)
        return out

    def replaced(self, **changes) -> AttitudeSolution:
        """Return ``dataclasses.replace(self, **changes)``, a fit's matrix kept unbuilt.

        ``dataclasses.replace`` reads every field, which would make the Rotation of a matrix
        given (~50 us, that a centroid solve need not pay); the rotation is passed on as
        stored, a Rotation or the matrix. Without a new rotation the instance's fields are
        copied as stored (the class has no ``__post_init__``).
        """
        if "rotation" in changes or not _FIELDS.issuperset(changes):
            stored = self.__dict__
            rotation = stored["_rotation"] if stored["_rotation"] is not None else stored["_matrix"]
            return replace(self, **{"rotation": rotation, **changes})
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__, **changes)
        return out

    @property
    def chi2_dof(self) -> int:
        """Degrees of freedom of ``2 * loss``: two per star, less the three attitude angles."""
        return 2 * self.n_stars - 3


# A rotation matrix given by a fit is orthonormal to rounding: scipy's re-orthogonalisation is
# skipped where scipy allows it (>= 1.15).
try:
    Rotation.from_matrix(np.eye(3), assume_valid=True)
    _VALID_MATRIX: dict = {"assume_valid": True}
except TypeError:  # pragma: no cover - scipy < 1.15
    _VALID_MATRIX = {}


class _RotationField:
    """AttitudeSolution's ``rotation``: a Rotation, or its matrix made one when first read.

    A matrix given is kept as given (``_matrix``): :attr:`AttitudeSolution.matrix` returns
    it whether or not the Rotation has been built.
    """

    def __get__(self, obj: object, objtype: type | None = None) -> Rotation:
        if obj is None:
            return self  # type: ignore[return-value]
        stored = obj.__dict__
        value = stored["_rotation"]
        if value is None:
            value = stored["_rotation"] = Rotation.from_matrix(stored["_matrix"], **_VALID_MATRIX)
        return value

    def __set__(self, obj: object, value: object) -> None:
        if isinstance(value, np.ndarray):
            obj.__dict__.update(_matrix=value, _rotation=None)
        else:
            obj.__dict__.update(_matrix=None, _rotation=value)


# installed after the dataclass is made: its __init__ stores the field through it
AttitudeSolution.rotation = _RotationField()  # type: ignore[assignment]

#: AttitudeSolution's fields, and the defaults of those with one (AttitudeSolution.of_fit)
_FIELDS = frozenset(f.name for f in fields(AttitudeSolution))
_DEFAULTS = {f.name: f.default for f in fields(AttitudeSolution) if f.default is not MISSING}


def cross3(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cross product of 3-vectors along the last axis (``np.cross`` without its overhead)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _as_vector_array(value: ArrayLike, name: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of shape (N, 3) of real numbers") from exc
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (N, 3), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        row = int(np.argwhere(~np.isfinite(arr))[0, 0])
        raise InputError(f"{name}[{row}] = {arr[row].tolist()} is not finite")
    return arr


def validate_observations(
    body_vectors: ArrayLike, reference_vectors: ArrayLike, sigma_rad: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], tuple[str, ...]]:
    """Check and normalise the inputs of an attitude estimator.

    Parameters
    ----------
    body_vectors : array_like, shape (N, 3)
        Measured directions in the camera frame; need not be unit length (they are normalised).
    reference_vectors : array_like, shape (N, 3)
        The same stars' catalogue directions, ICRS; normalised likewise.
    sigma_rad : float or array_like, shape (N,)
        Per-axis angular noise of each measured direction, rad, > 0.

    Returns
    -------
    body : ndarray, shape (N, 3)
        Unit camera-frame vectors.
    reference : ndarray, shape (N, 3)
        Unit ICRS vectors.
    sigma : ndarray, shape (N,)
        Per-star sigma, rad.
    notes : tuple of str
        A note for each input that had to be renormalised.

    Raises
    ------
    InputError
        Wrong or mismatched shapes, fewer than two stars, non-finite values, zero vectors,
        non-positive or non-finite sigma.
    """
    body = _as_vector_array(body_vectors, "body_vectors")
    ref = _as_vector_array(reference_vectors, "reference_vectors")
    if body.shape != ref.shape:
        raise InputError(
            f"body_vectors (shape {body.shape}) and reference_vectors (shape {ref.shape}) "
            "must have the same shape (N, 3)"
        )
    n = body.shape[0]
    if n < 2:
        raise InputError(
            f"need at least 2 star pairs to determine an attitude, got {n}; a single direction "
            "leaves the rotation about it free"
        )
    try:
        sigma = np.asarray(sigma_rad, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"sigma_rad must be a positive number or array, got {sigma_rad!r}"
        ) from exc
    if sigma.ndim == 0:
        sigma = np.full(n, float(sigma))
    if sigma.shape != (n,):
        raise InputError(
            f"sigma_rad must be a scalar or have shape ({n},), got shape {sigma.shape}"
        )
    bad = ~(np.isfinite(sigma) & (sigma > 0))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise InputError(f"sigma_rad[{i}] = {sigma[i]} is not allowed; must be finite and > 0 rad")

    notes: list[str] = []
    out = []
    for name, arr in (("body_vectors", body), ("reference_vectors", ref)):
        norm = np.linalg.norm(arr, axis=1)
        if np.any(norm == 0):
            i = int(np.argmax(norm == 0))
            raise InputError(f"{name}[{i}] is the zero vector; directions must be non-zero")
        off = np.abs(norm - 1.0) > UNIT_NORM_TOLERANCE
        if np.any(off):
            notes.append(
                f"{int(off.sum())} of {n} {name} were not unit length "
                f"(norms {norm.min():.6g}..{norm.max():.6g}); normalised"
            )
        out.append(arr / norm[:, None])
    return out[0], out[1], sigma, tuple(notes)


def wahba_residuals(
    rotation: Rotation,
    body: NDArray[np.float64],
    reference: NDArray[np.float64],
    *,
    sigma_rad: NDArray[np.float64],
) -> tuple[NDArray[np.float64], float]:
    """Per-star residual angles and the Wahba loss of an attitude.

    Parameters
    ----------
    rotation : Rotation
        Attitude, ICRS -> camera.
    body, reference : ndarray, shape (N, 3)
        Unit camera-frame and ICRS vectors.
    sigma_rad : ndarray, shape (N,)
        Per-star sigma, rad.

    Returns
    -------
    residuals_rad : ndarray, shape (N,)
        ``atan2(|b_i x A r_i|, b_i . A r_i)``, rad (accurate for tiny angles).
    loss : float
        ``1/2 sum_i sigma_i^-2 |b_i - A r_i|^2``.
    """
    predicted = rotation.apply(reference)
    cross = np.linalg.norm(cross3(body, predicted), axis=1)
    dot = np.einsum("ij,ij->i", body, predicted)
    residuals = np.arctan2(cross, dot)
    chord2 = np.sum((body - predicted) ** 2, axis=1)
    loss = 0.5 * float(np.sum(chord2 / sigma_rad**2))
    return residuals, loss


class Estimator:
    """Base of the estimators: validate, solve (subclass), then covariance and residuals.

    Subclasses implement ``_solve(body, reference, sigma) -> (rotation, covariance, notes)``
    and set ``method``.
    """

    method: str = ""

    def _solve(
        self,
        body: NDArray[np.float64],
        reference: NDArray[np.float64],
        sigma: NDArray[np.float64],
    ) -> tuple[Rotation, NDArray[np.float64], tuple[str, ...], str]:
        raise NotImplementedError

    def __call__(
        self, body_vectors: ArrayLike, reference_vectors: ArrayLike, sigma_rad: ArrayLike
    ) -> AttitudeSolution:
        """Estimate the attitude from matched star directions.

        Parameters
        ----------
        body_vectors : array_like, shape (N, 3)
            Measured star directions in the camera frame (unit; others are normalised).
        reference_vectors : array_like, shape (N, 3)
            The same stars' catalogue directions, ICRS.
        sigma_rad : float or array_like, shape (N,)
            Per-axis angular noise of each measured direction, rad; weights are sigma^-2.

        Returns
        -------
        AttitudeSolution

        Raises
        ------
        InputError
            Bad shapes, N < 2, non-finite values, zero vectors, sigma <= 0.
        SingularGeometryError
            The stars do not determine the attitude (all parallel or antipodal).
        """
        start = time.perf_counter()
        body, ref, sigma, notes = validate_observations(body_vectors, reference_vectors, sigma_rad)
        rotation, cov, solve_notes, method = self._solve(body, ref, sigma)
        residuals, loss = wahba_residuals(rotation, body, ref, sigma_rad=sigma)
        return AttitudeSolution(
            rotation=rotation,
            covariance_rad2=cov,
            residual_rms_rad=float(np.sqrt(np.mean(residuals**2))),
            residuals_rad=residuals,
            method=method,
            n_stars=body.shape[0],
            loss=loss,
            notes=notes + solve_notes,
            elapsed_s=time.perf_counter() - start,
        )
