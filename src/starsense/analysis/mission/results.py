"""Results of a mission availability run: per-head timelines, outages and the combined head set.

A head's outcome at a step follows the tracker's logic (Dzamba & Enright 2014, sec. 1.1):
from lost-in-space it needs ``N_min = 3`` detected stars to acquire; once acquired it keeps
tracking while at least 2 are detected, and falls back to lost-in-space below that. A head is
available while it has an attitude (acquired or tracking); the spacecraft has one while any
head does. An outage is a maximal run of unavailable steps (one at the start or the end of the
span counts, truncated by the span).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from starsense.units import DEG

__all__ = ["HeadTimeline", "MissionResult", "outages", "tracking_state"]


def tracking_state(ok_track: NDArray[np.bool_], ok_lis: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Return whether the head has an attitude at each step (acquired or still tracking).

    True at step k when enough stars to track are detected at k (`ok_track`) and a lost-in-space
    solution (`ok_lis`) happened at or after the start of the current run of `ok_track`.
    Vectorised with running maxima (no loop over steps).
    """
    idx = np.arange(ok_track.size)
    prev = np.concatenate([[False], ok_track[:-1]])
    run_start = np.maximum.accumulate(np.where(ok_track & ~prev, idx, -1))
    last_lis = np.maximum.accumulate(np.where(ok_lis, idx, -1))
    return ok_track & (last_lis >= run_start) & (last_lis >= 0)


def outages(available: NDArray[np.bool_], step_s: float) -> tuple[int, float, NDArray[np.intp]]:
    """Return (number of outages, longest outage in s, (K, 2) start/stop step indices)."""
    a = np.asarray(available, dtype=bool)
    d = np.diff(np.concatenate([[False], ~a, [False]]).astype(np.int8))
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1)  # stop: first step after
    spans = np.stack([starts, stops], axis=1)
    longest = float((stops - starts).max() * step_s) if starts.size else 0.0
    return int(starts.size), longest, spans


@dataclass(frozen=True, eq=False)
class HeadTimeline:
    """One head's outcome at every step.

    Attributes
    ----------
    name : str
    stars : ndarray of int32, shape (N,)
        Stars detected (inside the field, no fainter than m_t(w); 0 when blinded).
    rate_rad_s : ndarray, shape (N,)
        Cross-boresight angular rate of the head, rad/s.
    sun_sep, moon_sep : ndarray, shape (N,)
        Angle from the boresight to the Sun and the Moon, rad.
    earth_limb_angle : ndarray, shape (N,)
        Angle from the boresight to the Earth's limb raised by the atmosphere, rad (negative:
        the boresight is on the Earth's disc).
    sun_blinded, moon_blinded, earth_blinded : ndarray of bool, shape (N,)
    lost_in_space : ndarray of bool, shape (N,)
        At least N_min stars detected: a lost-in-space solution is possible.
    available : ndarray of bool, shape (N,)
        The head has an attitude (see :func:`tracking_state`).
    info : dict
        The head's description (:meth:`Head.describe`).
    """

    name: str
    stars: NDArray[np.int32]
    rate_rad_s: NDArray[np.float64]
    sun_sep: NDArray[np.float64]
    moon_sep: NDArray[np.float64]
    earth_limb_angle: NDArray[np.float64]
    sun_blinded: NDArray[np.bool_]
    moon_blinded: NDArray[np.bool_]
    earth_blinded: NDArray[np.bool_]
    lost_in_space: NDArray[np.bool_]
    available: NDArray[np.bool_]
    info: dict = field(default_factory=dict)

    def summary(self, step_s: float) -> dict:
        """Return the head's JSON entry (fractions of the steps; times in s)."""
        n_out, longest, _ = outages(self.available, step_s)
        n = self.available.size
        return {
            "name": self.name,
            "available_fraction": float(self.available.mean()),
            "sun_blinded_fraction": float(self.sun_blinded.mean()),
            "moon_blinded_fraction": float(self.moon_blinded.mean()),
            "earth_blinded_fraction": float(self.earth_blinded.mean()),
            "outages": n_out,
            "longest_outage_s": longest,
            "lost_in_space_fraction": float(self.lost_in_space.mean()),
            "blinded_s": {
                body: float(getattr(self, f"{body}_blinded").sum() * step_s)
                for body in ("sun", "moon", "earth")
            },
            "mean_stars": float(self.stars.mean()),
            "max_rate_deg_s": float(self.rate_rad_s.max() / DEG) if n else 0.0,
            **{k: v for k, v in self.info.items() if k != "name"},
        }


@dataclass(frozen=True, eq=False)
class MissionResult:
    """Availability of a set of heads along a mission.

    Attributes
    ----------
    t_s : ndarray, shape (N,)
        Step times from the start, s.
    step_s : float
    heads : list of HeadTimeline
    combined : ndarray of bool, shape (N,)
        Any head available.
    meta : dict
        Start, orbit, attitude profile, n_min (JSON-ready).
    """

    t_s: NDArray[np.float64]
    step_s: float
    heads: list
    combined: NDArray[np.bool_]
    meta: dict = field(default_factory=dict)

    @property
    def steps(self) -> int:
        """Number of time steps."""
        return int(self.t_s.size)

    def to_dict(self) -> dict:
        """Return the result as the JSON of ``starsense availability mission --json``."""
        n_out, longest, _ = outages(self.combined, self.step_s)
        return {
            "steps": self.steps,
            "step_s": self.step_s,
            "heads": [h.summary(self.step_s) for h in self.heads],
            "combined": {
                "available_fraction": float(self.combined.mean()),
                "outages": n_out,
                "longest_outage_s": longest,
            },
            **self.meta,
        }

    def lines(self) -> list[str]:
        """Return a human-readable summary."""
        d = self.to_dict()
        out = [
            f"{self.meta.get('orbit', '')}; {self.meta.get('attitude', '')}; {d['steps']} steps "
            f"of {self.step_s:g} s from {self.meta.get('start', '')}"
        ]
        for h in d["heads"]:
            b = h["blinded_s"]
            out.append(
                f"  {h['name']:<12} available {100 * h['available_fraction']:6.2f} %  "
                f"outages {h['outages']:4d}  longest {h['longest_outage_s']:8.0f} s  blinded: "
                f"Sun {b['sun']:.0f} s, Moon {b['moon']:.0f} s, Earth {b['earth']:.0f} s"
            )
        c = d["combined"]
        out.append(
            f"  {'combined':<12} available {100 * c['available_fraction']:6.2f} %  "
            f"outages {c['outages']:4d}  longest {c['longest_outage_s']:8.0f} s"
        )
        return out
