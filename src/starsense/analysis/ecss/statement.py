"""The ECSS-E-ST-60-20C performance statement of a sensor: per axis, at a confidence, per rate.

:func:`ecss_statement` takes the sensor's datasheet (its limiting magnitude, its slew curve,
its sky of attitudes and stars: :func:`starsense.analysis.datasheet.build_datasheet`) and
gives every error term (:mod:`starsense.analysis.ecss.terms`) per axis X, Y (cross-boresight,
apart) and Z (about the boresight) at each rate, at the confidence asked: a Gaussian term is
``k`` times its sky-median 1-sigma (``k`` of :func:`~starsense.analysis.ecss.confidence.
gaussian_factor`), and the sky ensemble's bound (:func:`~starsense.analysis.ecss.confidence.
mixture_bound`) is given beside it. At each rate every term says whether it acts as a bias or
as noise (:func:`~starsense.analysis.ecss.classes.acting`); the totals are the root sum
squares of the terms counted, of the biases, of the noises, and of both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from starsense.analysis.datasheet import DatasheetSettings, build_datasheet
from starsense.analysis.ecss.classes import CLASSES, acting
from starsense.analysis.ecss.confidence import gaussian_factor, mixture_bound, weighted_median
from starsense.analysis.ecss.sky import sky_stars
from starsense.analysis.ecss.terms import error_terms
from starsense.analysis.inputs import as_catalog
from starsense.errors import InputError
from starsense.photometry.colour import with_johnson_from_gaia
from starsense.units import DEG, RAD_TO_ARCSEC

__all__ = [
    "AXES",
    "MIN_SOLVING_ATTITUDES",
    "SCHEMA",
    "Statement",
    "ecss_statement",
    "effective_attitudes",
]

#: the JSON's schema name and version
SCHEMA = "starsense.ecss/1"
#: the axes, camera frame: X, Y across the boresight (columns, rows), Z about it
AXES = ("x", "y", "z")


def _arcsec(x) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x) * RAD_TO_ARCSEC


@dataclass(frozen=True)
class Statement:
    """The statement (module docstring); :meth:`to_dict` is its JSON.

    Attributes
    ----------
    sensor : str
    confidence : float
        Probability each value is not exceeded (two-sided, per axis).
    gaussian_factor : float
        ``k`` of the confidence for a Gaussian error.
    rates_deg_s : tuple of float
    terms : tuple of dict
        Per term: ``key``, ``ecss_class``, ``distribution``, ``source``, ``gaussian``,
        ``counted`` and ``at_rate``: per rate ``rate_deg_s``, ``acts_as``, ``time_class``,
        ``period_s``, and per axis ``{axis}_arcsec`` (at the confidence), ``{axis}_1sigma_arcsec``
        (sky median) and ``{axis}_sky_ensemble_arcsec`` (None where not known).
    totals : tuple of dict
        Per rate: ``rate_deg_s`` and ``{total,total_bias,total_noise}_{axis}_arcsec``, with
        ``not_known``: the keys of the counted terms left out because they are not known, and
        ``total_sky_ensemble_{axis}_arcsec``: the bound an error at a random attitude of the
        sky stays within at the confidence (None where not known).
    notes : tuple of str
    sources : tuple of Term
        The terms' values per attitude (:mod:`starsense.analysis.ecss.terms`), rad, behind
        :meth:`at_confidence` (not in the JSON).
    geometry : tuple of float
        The field's narrower width and one pixel, rad (the crossing periods).
    solving : tuple of dict
        Per rate, each attitude's chance of a solution (the weights of the sky medians and
        ensembles), keyed by the number of attitudes it weighs: all of the sky's, and those of
        the terms computed on every :attr:`~starsense.analysis.ecss.sky.SkyStars.rate_stride`-th.
    """

    sensor: str
    confidence: float
    gaussian_factor: float
    rates_deg_s: tuple
    terms: tuple
    totals: tuple
    notes: tuple
    sources: tuple = field(default=(), repr=False, compare=False)
    geometry: tuple = field(default=(), repr=False, compare=False)
    solving: tuple = field(default=(), repr=False, compare=False)

    def at_confidence(self, confidence: float) -> Statement:
        """Return the same statement at another confidence (the same terms, rates and sky).

        Parameters
        ----------
        confidence : float
            Probability in (0, 1).

        Returns
        -------
        Statement
        """
        if not self.sources:
            raise ValueError("this statement keeps no terms to restate (built by hand)")
        return _assemble(
            self.sensor, self.sources, self.rates_deg_s, confidence, self.geometry, self.solving
        )

    def values(self) -> list[dict]:
        """Return, per rate, the flat ``{term}_{axis}_arcsec`` values (None: not known)."""
        out = []
        for i, rate in enumerate(self.rates_deg_s):
            row = {"rate_deg_s": rate}
            for t in self.terms:
                row |= {f"{t['key']}_{a}_arcsec": t["at_rate"][i][f"{a}_arcsec"] for a in AXES}
            row |= {  # the sums of the rows (the ensemble total is not one: see totals)
                k: v
                for k, v in self.totals[i].items()
                if k.endswith("_arcsec") and not k.startswith("total_sky_ensemble")
            }
            out.append(row)
        return out

    def to_dict(self) -> dict:
        """Return the statement as JSON-ready data (``starsense ecss --json``)."""
        return {
            "schema": SCHEMA,
            "sensor": self.sensor,
            "confidence": self.confidence,
            "gaussian_factor": self.gaussian_factor,
            "rates_deg_s": list(self.rates_deg_s),
            "axes": {
                "x": "across the boresight, along the columns",
                "y": "across the boresight, along the rows",
                "z": "about the boresight (roll)",
            },
            "terms": list(self.terms),
            "totals": list(self.totals),
            "values": self.values(),
            "notes": list(self.notes),
        }


#: the fewest attitudes' worth of solving chances (Kish's effective number, ``(sum w)^2 /
#: sum w^2``) whose weighted sky statistics describe the attitudes that solve. With fewer, one or
#: two attitudes, each turned about its one rate direction, make the value: esa_blackfly at
#: 2 deg/s weighed a single attitude (effective number 1.0) whose X noise was its rest value
MIN_SOLVING_ATTITUDES = 20


def effective_attitudes(w) -> float:
    """Return Kish's effective number of attitudes of the weights ``w`` (0 for none)."""
    w = np.asarray(w, dtype=float)
    total = float(np.sum(w))
    return total * total / float(np.sum(w * w)) if total > 0.0 else 0.0


def _weights(solving: tuple, i: int, n: int):
    """Return the solving chances of rate ``i`` over ``n`` attitudes (None: unweighted).

    Where fewer than :data:`MIN_SOLVING_ATTITUDES` attitudes' worth can solve at that rate, the
    values are those of every attitude (what the sensor would do if it solved, the poorer fields
    with the rest: conservative; its availability says how seldom it does).
    """
    w = solving[i].get(n) if solving else None
    if w is None or effective_attitudes(w) < MIN_SOLVING_ATTITUDES:
        return None
    return w


def _thin_rates(solving: tuple, rates: tuple) -> list[str]:
    """Return the rates (deg/s, as text) at which too few attitudes solve to weigh them."""
    return [
        f"{r:g}"
        for i, r in enumerate(rates)
        if solving
        and any(effective_attitudes(w) < MIN_SOLVING_ATTITUDES for w in solving[i].values())
    ]


def _at_rate(term, i: int, rate_rad_s: float, k: float, p: float, geometry, solving) -> dict:
    act = acting(term.ecss_class, rate_rad_s, field_rad=geometry[0], pixel_rad=geometry[1])
    out = {
        "rate_deg_s": rate_rad_s / DEG,
        "acts_as": act.acts_as,
        "time_class": act.time_class,
        "period_s": act.period_s,
    }
    v = term.values_rad[i]
    scale = k if term.gaussian else 1.0
    for j, a in enumerate(AXES):
        if v is None:
            one = ens = None
        elif np.ndim(v) == 2:
            col = v[:, j]
            w = _weights(solving, i, len(col))
            one = weighted_median(col, w)
            ens = mixture_bound(col, p, w) if term.gaussian else one
        else:
            one = float(v[j])
            ens = scale * one
        out[f"{a}_arcsec"] = _arcsec(None if one is None else scale * one)
        out[f"{a}_1sigma_arcsec"] = _arcsec(one)
        out[f"{a}_sky_ensemble_arcsec"] = _arcsec(ens)
    return out


def _totals(terms: list[dict], counted: dict, i: int, rate_deg_s: float) -> dict:
    """Root sum squares per axis of the counted terms: all, biases, noises."""
    out: dict = {"rate_deg_s": rate_deg_s}
    missing = []
    for t in terms:
        if counted[t["key"]] and t["at_rate"][i]["x_arcsec"] is None:
            missing.append(t["key"])
    for a in AXES:
        parts = {"bias": 0.0, "noise": 0.0}
        for t in terms:
            row = t["at_rate"][i]
            if counted[t["key"]] and row[f"{a}_arcsec"] is not None:
                parts[row["acts_as"]] += row[f"{a}_arcsec"] ** 2
        out[f"total_bias_{a}_arcsec"] = math.sqrt(parts["bias"])
        out[f"total_noise_{a}_arcsec"] = math.sqrt(parts["noise"])
        out[f"total_{a}_arcsec"] = math.sqrt(parts["bias"] + parts["noise"])
    out["not_known"] = missing
    return out


def _ensemble_totals(terms: tuple, i: int, p: float, solving: tuple) -> dict:
    """Return the total that an error at a random attitude of the sky stays within, with ``p``.

    Per attitude, the counted Gaussian terms' 1-sigmas add in quadrature (a term with one value
    adds it at every attitude); the bound of that mixture at ``p``
    (:func:`~starsense.analysis.ecss.confidence.mixture_bound`) then adds in quadrature to the
    counted worst-case terms. Terms known per attitude over different skies (lengths that do not
    match) give None.
    """
    out = {}
    for j, a in enumerate(AXES):
        var, bounds, size = 0.0, 0.0, None
        for t in terms:
            v = t.values_rad[i]
            if not t.counted or v is None:
                continue
            if not t.gaussian:
                one = v[j]
                if np.ndim(v) == 2:
                    one = weighted_median(v[:, j], _weights(solving, i, len(v)))
                    one = math.nan if one is None else one
                bounds += float(one) ** 2 if math.isfinite(one) else 0.0
                continue
            col = np.asarray(v[:, j] if np.ndim(v) == 2 else v[j], dtype=float)
            if col.ndim and size is not None and col.size != size:
                size = -1
                break
            size = col.size if col.ndim else size
            var = var + col**2
        q = None
        if size != -1:
            sig = np.sqrt(np.atleast_1d(var))
            q = mixture_bound(sig, p, _weights(solving, i, len(sig)) if np.ndim(var) else None)
        out[f"total_sky_ensemble_{a}_arcsec"] = (
            None if q is None else math.sqrt(q**2 + bounds) * RAD_TO_ARCSEC
        )
    return out


def check_rates(rates_deg_s) -> tuple[float, ...]:
    """Return the rates (deg/s) as sorted unique floats; InputError on a bad one."""
    out = []
    for r in rates_deg_s:
        try:
            x = float(r)
        except (TypeError, ValueError):
            raise InputError(f"rate {r!r} is not a number (deg/s)") from None
        if not math.isfinite(x) or x < 0.0 or x > 30.0:
            raise InputError(f"rate {r!r} deg/s is out of range; must be in [0, 30]")
        out.append(x)
    if not out:
        raise InputError("no rate given; give at least one (deg/s), e.g. 0,1")
    return tuple(sorted(set(out)))


def ecss_statement(
    sensor,
    catalog=None,
    *,
    confidence: float = 0.6826894921370859,
    rates_deg_s=None,
    settings: DatasheetSettings | None = None,
    sheet=None,
) -> Statement:
    """Return the ECSS performance statement of ``sensor`` (module docstring).

    Parameters
    ----------
    sensor : Sensor
    catalog : Catalog, optional
        Default: the bundled Hipparcos.
    confidence : float
        Probability in (0, 1) (:func:`~starsense.analysis.ecss.confidence.parse_confidence`).
    rates_deg_s : sequence of float, optional
        Body rates, deg/s (default: 0 and the datasheet's check rate).
    settings : DatasheetSettings, optional
        How the datasheet is computed (default: its defaults with no Monte Carlo frames).
    sheet : Datasheet, optional
        The datasheet of ``sensor`` built with ``settings`` (built here when not given).

    Returns
    -------
    Statement
    """
    if not 0.0 < float(confidence) < 1.0:
        raise InputError(f"confidence = {confidence!r} must lie strictly between 0 and 1")
    st = settings or DatasheetSettings(n_trials=0)
    rates = check_rates((0.0, st.rate_rad_s / DEG) if rates_deg_s is None else rates_deg_s)
    cat, _ = with_johnson_from_gaia(as_catalog(catalog))
    sheet = sheet if sheet is not None else build_datasheet(sensor, cat, settings=st)
    if sheet.limiting_magnitude is None:
        raise InputError(f"{sensor.name} detects no star at rest: it has no statement")
    sky = sky_stars(sensor, cat, st, limit_mag=sheet.limiting_magnitude, slew=sheet.slew)
    rates_rad = [r * DEG for r in rates]
    terms = error_terms(
        sensor,
        sky,
        st,
        limit_mag=sheet.limiting_magnitude,
        rates_rad_s=rates_rad,
    )
    geometry = (2.0 * min(sensor.half_fov_rad), sky.model.pixel_rad)
    solving = []
    for r in rates_rad:
        w = sky.solving(r)
        solving.append({len(w): w, len(w[:: sky.rate_stride]): w[:: sky.rate_stride]})
    return _assemble(sensor.name, tuple(terms), rates, confidence, geometry, tuple(solving))


def _assemble(
    name: str, terms: tuple, rates: tuple, confidence: float, geometry, solving: tuple = ()
) -> Statement:
    """Return the statement of ``terms`` at ``rates`` (deg/s) and ``confidence``."""
    if not 0.0 < float(confidence) < 1.0:
        raise InputError(f"confidence = {confidence!r} must lie strictly between 0 and 1")
    k, p = gaussian_factor(confidence), float(confidence)
    rates_rad = [r * DEG for r in rates]
    rows = [
        {
            "key": t.key,
            "ecss_class": t.ecss_class,
            "ecss_name": CLASSES[t.ecss_class],
            "distribution": t.distribution,
            "source": t.source,
            "gaussian": t.gaussian,
            "counted": t.counted,
            "at_rate": [
                _at_rate(t, i, r, k, p, geometry, solving) for i, r in enumerate(rates_rad)
            ],
        }
        for t in terms
    ]
    counted = {t.key: t.counted for t in terms}
    totals = tuple(
        _totals(rows, counted, i, r) | _ensemble_totals(terms, i, p, solving)
        for i, r in enumerate(rates)
    )
    notes = (
        f"values at {100 * p:.4g} % (two-sided, per axis): k = {k:.4g} times the sky-median "
        "1-sigma for Gaussian terms; the sky ensemble bound (a random attitude) beside it",
        "spatial errors act as biases at rest (inertial pointing) and as noise under slew "
        "(ECSS-E-ST-60-20C): their amplitude is the one at rest, their period the crossing "
        "time of the field (FOV) or of a pixel (PSE)",
        "totals: root sum square of the counted terms at the confidence, per axis; the sky "
        "ensemble total: the bound at a random attitude (each attitude's Gaussian terms in "
        "quadrature, the mixture's bound at the confidence, the worst-case terms in quadrature)",
        "the sky medians and ensembles are over the attitudes that give a solution: each "
        "attitude weighs its chance of detecting the stars lost in space needs at that rate "
        "(the availability's count); the availability is stated apart",
    )
    thin = _thin_rates(solving, rates)
    if thin:
        notes += (
            f"at {', '.join(thin)} deg/s fewer than {MIN_SOLVING_ATTITUDES} attitudes' worth "
            "of the sky solve: the values there are over every attitude, poorer fields included "
            "(conservative)",
        )
    return Statement(name, p, k, rates, tuple(rows), totals, notes, terms, tuple(geometry), solving)
