"""The stellar detection threshold against slew rate, ``m_t(w)`` (Dzamba & Enright 2014, Fig. 10).

Rates are rad/s; the JSON of ``starsense slew tolerance --json`` (deg/s) is read by
:meth:`ThresholdCurve.from_tolerance_dict` and written by :meth:`ThresholdCurve.to_dict`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from starsense.analysis.availability.checks import check_mag, check_rates
from starsense.errors import InputError
from starsense.units import DEG, to_edge

__all__ = ["ThresholdCurve"]


@dataclass(frozen=True)
class ThresholdCurve:
    """The detection threshold against slew rate, ``m_t(w)``: Fig. 10 read sideways.

    A star is detected at slew rate ``w`` when its magnitude is ``<= m_t(w)``. Between knots
    ``m_t`` is interpolated linearly; before the first knot and after the last it is held at the
    end value, except that above ``max_rate_rad_s`` nothing is detected (``m_t = -inf``).

    Parameters
    ----------
    rates_rad_s : array_like, shape (K,)
        Knot rates, rad/s: finite, >= 0, strictly increasing.
    max_mag : array_like, shape (K,)
        Threshold magnitude at each knot (finite).
    max_rate_rad_s : float
        Rate above which no star is detected, rad/s (``inf``: none; must be >= the last knot).
    label : str
        What the curve is (e.g. ``"st16, reed model"``), for reports.

    Raises
    ------
    InputError
        On an empty, unsorted, negative or non-finite knot, or mismatched lengths.
    """

    rates_rad_s: NDArray[np.float64]
    max_mag: NDArray[np.float64]
    max_rate_rad_s: float = math.inf
    label: str = ""

    def __post_init__(self) -> None:
        """Check the knots and freeze the arrays."""
        rates = check_rates(self.rates_rad_s, "ThresholdCurve.rates_rad_s")
        try:
            mags = np.atleast_1d(np.asarray(self.max_mag, dtype=np.float64))
        except (TypeError, ValueError):
            raise InputError(
                f"ThresholdCurve.max_mag must be numbers, got {self.max_mag!r}"
            ) from None
        if mags.shape != rates.shape:
            raise InputError(
                f"ThresholdCurve.max_mag has {mags.size} values for {rates.size} rates; "
                "give one magnitude per rate"
            )
        if not np.all(np.isfinite(mags)):
            raise InputError(f"ThresholdCurve.max_mag must be finite, got {mags.tolist()}")
        if np.any(np.diff(rates) <= 0):
            raise InputError(
                f"ThresholdCurve.rates_rad_s must be strictly increasing, got {rates.tolist()}"
            )
        top = float(self.max_rate_rad_s)
        if math.isnan(top) or top < rates[-1]:
            raise InputError(
                f"ThresholdCurve.max_rate_rad_s = {self.max_rate_rad_s!r} must be >= the last "
                f"knot rate {rates[-1]:g} rad/s"
            )
        for name, value in (("rates_rad_s", rates), ("max_mag", mags)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "max_rate_rad_s", top)

    @property
    def rates_deg_s(self) -> NDArray[np.float64]:
        """Knot rates, deg/s (for output)."""
        return to_edge(self.rates_rad_s, DEG)

    @property
    def max_rate_deg_s(self) -> float:
        """Rate above which no star is detected, deg/s (for output)."""
        return float(to_edge(self.max_rate_rad_s, DEG))

    @classmethod
    def constant(cls, max_mag: float, label: str = "") -> ThresholdCurve:
        """Return a threshold that does not depend on rate (static detection at every rate)."""
        mag = check_mag(max_mag, "max_mag")
        return cls(np.array([0.0]), np.array([mag]), label=label or f"m_t = {mag:g}")

    @classmethod
    def from_tolerance(
        cls,
        magnitudes: ArrayLike,
        tolerable_rate_rad_s: Sequence[float | None],
        *,
        capped: ArrayLike | None = None,
        grid_max_rate_rad_s: float | None = None,
        label: str = "",
    ) -> ThresholdCurve:
        """Invert a tolerable-slew curve (magnitude -> fastest rate still detected, Fig. 10).

        The tolerable rate is first made monotonic (a brighter star tolerates at least the rate
        of a fainter one: a running minimum from bright to faint). Magnitudes never detected
        (``None``) are dropped. Each remaining magnitude ``m_k`` with tolerable rate ``r_k``
        becomes a knot ``(r_k, m_k)`` (of equal rates the faintest magnitude is kept), so that
        ``m_t`` interpolates the piecewise-linear inverse of Fig. 10. Magnitudes detected at every
        simulated rate (``capped``) are placed at the grid's top rate and ``m_t`` is held there
        beyond it; without capped magnitudes nothing is detected above the brightest
        magnitude's tolerable rate. At rates below the faintest detected magnitude's tolerable
        rate ``m_t`` is that magnitude: the faint limit of the simulated grid, so give a grid
        reaching past the catalogue's limit.

        Parameters
        ----------
        magnitudes : array_like, shape (M,)
            Simulated magnitudes.
        tolerable_rate_rad_s : sequence of float or None, length M
            Fastest rate at which each magnitude is still detected, rad/s; None if not even at
            rest.
        capped : array_like of bool, shape (M,), optional
            Detected at every rate of the grid.
        grid_max_rate_rad_s : float, optional
            Top rate of the simulated grid, rad/s (default: the largest tolerable rate).
        label : str
            What the curve is, for reports.

        Returns
        -------
        ThresholdCurve

        Raises
        ------
        InputError
            If no magnitude is detected at rest, or the inputs disagree in length.
        """
        mags = np.atleast_1d(np.asarray(magnitudes, dtype=np.float64))
        tol_list = list(tolerable_rate_rad_s)
        if len(tol_list) != mags.size or mags.size == 0:
            raise InputError(
                f"tolerable-slew curve: {len(tol_list)} rates for {mags.size} magnitudes; "
                "give one rate (or None) per magnitude"
            )
        cap = np.zeros(mags.size, bool) if capped is None else np.asarray(capped, dtype=bool)
        if cap.shape != mags.shape:
            raise InputError("tolerable-slew curve: 'capped' needs one flag per magnitude")
        tol = np.array([-np.inf if r is None else float(r) for r in tol_list])
        if np.any(np.isnan(tol)) or np.any(np.isnan(mags)):
            raise InputError("tolerable-slew curve: magnitudes and rates must not be NaN")
        finite_tol = tol[np.isfinite(tol)]
        top = (
            float(grid_max_rate_rad_s)
            if grid_max_rate_rad_s is not None
            else float(finite_tol.max())
            if finite_tol.size
            else 0.0
        )
        tol = np.where(cap, np.inf, tol)
        order = np.argsort(mags, kind="stable")
        mags, tol = mags[order], tol[order]
        tol = np.minimum.accumulate(tol)  # non-increasing from bright to faint
        seen = tol > -np.inf
        if not seen.any():
            raise InputError(
                "tolerable-slew curve: no magnitude is detected even at rest "
                f"(magnitudes {mags.min():g} ... {mags.max():g}); nothing can be available"
            )
        mags, tol = mags[seen], tol[seen]
        is_capped = np.isinf(tol)
        knot_rate = np.where(is_capped, max(top, 0.0), np.maximum(tol, 0.0))
        # one knot per distinct rate, keeping the faintest magnitude
        knots: dict[float, float] = {}
        for r, m in zip(knot_rate.tolist(), mags.tolist(), strict=True):
            knots[r] = max(m, knots.get(r, -np.inf))
        rates = np.array(sorted(knots))
        max_mag = np.array([knots[r] for r in rates])
        # a fainter magnitude at a faster knot cannot happen after the running minimum; keep the
        # curve non-increasing anyway (ties of rate resolved above)
        max_mag = np.minimum.accumulate(max_mag)
        max_rate = math.inf if is_capped.any() else float(rates[-1])
        return cls(rates, max_mag, max_rate, label)

    @classmethod
    def from_slew(cls, result: Any, label: str | None = None) -> ThresholdCurve:
        """Return the threshold curve of a :class:`~starsense.analysis.slew.SlewResult` (Fig. 10).

        See :meth:`from_tolerance`; the grid's top rate is the result's last simulated rate.
        """
        rates = np.asarray(result.rates_rad_s, dtype=np.float64)
        return cls.from_tolerance(
            result.magnitudes,
            result.tolerable_rate_rad_s,
            capped=result.capped,
            grid_max_rate_rad_s=float(rates[-1]) if rates.size else None,
            label=label if label is not None else f"{result.sensor_name}, {result.model} model",
        )

    @classmethod
    def from_tolerance_dict(cls, data: dict, source: str = "tolerance JSON") -> ThresholdCurve:
        """Read the JSON of ``starsense slew tolerance --json`` (rates in deg/s).

        Keys: ``magnitudes``, ``tolerable_rate_deg_s``, and optionally ``capped``,
        ``rates_deg_s``, ``sensor``, ``model``.
        """
        try:
            mags = data["magnitudes"]
            tol = data["tolerable_rate_deg_s"]
        except (KeyError, TypeError):
            raise InputError(
                f"{source}: expected the output of `starsense slew tolerance --json` with keys "
                "'magnitudes' and 'tolerable_rate_deg_s'"
            ) from None
        grid = data.get("rates_deg_s")
        label = ", ".join(
            str(data[k]) + (" model" if k == "model" else "")
            for k in ("sensor", "model")
            if k in data
        )
        try:
            tol_rad = [None if r is None else float(r) * DEG for r in tol]
            top = float(max(grid)) * DEG if grid else None
        except (TypeError, ValueError):
            raise InputError(f"{source}: rates must be numbers (or null)") from None
        try:
            return cls.from_tolerance(
                mags, tol_rad, capped=data.get("capped"), grid_max_rate_rad_s=top, label=label
            )
        except InputError as exc:
            raise InputError(f"{source}: {exc}") from None

    def __call__(self, rates_rad_s: ArrayLike) -> NDArray[np.float64]:
        """Return ``m_t`` at the given rates (rad/s, >= 0); ``-inf`` above ``max_rate_rad_s``."""
        rates = check_rates(rates_rad_s, "rate_rad_s")
        out = np.interp(rates, self.rates_rad_s, self.max_mag)
        out[rates > self.max_rate_rad_s] = -np.inf
        return out

    def to_dict(self) -> dict:
        """Return the curve as JSON-ready numbers (rates in deg/s)."""
        return {
            "rates_deg_s": self.rates_deg_s.tolist(),
            "max_mag": self.max_mag.tolist(),
            "max_rate_deg_s": None if math.isinf(self.max_rate_rad_s) else self.max_rate_deg_s,
            "label": self.label,
        }
