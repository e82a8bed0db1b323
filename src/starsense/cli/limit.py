"""`starsense limit`: the physical limit of attitude accuracy (Fialho & Mortari 2019).

Options are checked here, with their names in the messages, converted from degrees to radians
and handed to :mod:`starsense.analysis.limits` (or :mod:`starsense.scale` for HATS catalogues).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from starsense import plotting
from starsense._validate import check_count, check_scalar, finite_float
from starsense.analysis.limits.brightest import brightest_curve
from starsense.analysis.limits.centroid import centroid_fisher
from starsense.analysis.limits.photons import (
    MAX_PHOTON_TRIALS,
    PHOTON_TRIAL_COST,
    low_photon_degradation,
)
from starsense.analysis.limits.sky import fov_limit, sky_limit
from starsense.catalog import load_catalog
from starsense.catalog._columns import MAG_RANGE
from starsense.cli.catalog import check_dask_option, hats_session
from starsense.cli.common import (
    BRIGHTEST_MAG,
    CatalogOpt,
    ColourOpt,
    DaskOpt,
    DiameterOpt,
    ExposureOpt,
    JsonOpt,
    ScaleCatalogOpt,
    SeedOpt,
    check_aperture_options,
    colour_clamp_note,
    emit,
    option_float,
    output_file,
)
from starsense.errors import InputError
from starsense.geometry.projection import radec_to_vectors
from starsense.photometry import ColourModel, fit_star, total_photons
from starsense.photometry.stars import BlackBodyStars
from starsense.scale import brightest_curve as hats_curve
from starsense.scale import fov_limit as hats_fov_limit
from starsense.scale import sky_limit as hats_sky_limit
from starsense.units import DEG, RAD_TO_ARCSEC

limit_app = typer.Typer(
    help="The physical limit of attitude accuracy (Fialho & Mortari 2019).",
    no_args_is_help=True,
)


def _rad(x: float) -> str:
    return f"{x:.4g} rad ({x * RAD_TO_ARCSEC:.4g} arcsec)"


def _parse_target(text: str) -> tuple[float, float]:
    try:
        ra, dec = (float(p) for p in text.split(","))
    except ValueError:
        raise InputError(f"--target-deg expects RA,DEC in degrees, got {text!r}") from None
    if not (np.isfinite(ra) and np.isfinite(dec)) or not -90.0 <= dec <= 90.0:
        raise InputError(f"--target-deg {text!r}: RA must be finite and Dec within [-90, 90]")
    return ra, dec


def _target_vectors(radec: list[tuple[float, float]]) -> np.ndarray:
    """Return the ICRS unit vectors (T, 3) of (RA, Dec) pairs given in degrees."""
    return np.array([radec_to_vectors(ra * DEG, dec * DEG) for ra, dec in radec])


def _check_max_mag(max_mag: float | None) -> None:
    if max_mag is not None:
        finite_float(max_mag, "--max-mag")
        option_float(max_mag, "--max-mag", BRIGHTEST_MAG)


def _load_stars(catalog: str, max_mag: float | None, colour: str | None):
    _check_max_mag(max_mag)
    cat = load_catalog(catalog)
    stars = BlackBodyStars.from_catalog(cat, colour)
    if max_mag is not None:
        keep = stars.magnitude <= max_mag
        if keep.sum() < 2:
            raise InputError(
                f"--max-mag {max_mag} leaves {int(keep.sum())} star(s) of {len(stars)} in "
                f"{cat.name}; at least 2 are needed"
            )
        stars = stars.subset(keep)
    return cat, stars


@limit_app.command("star")
def limit_star(
    mag_v: Annotated[float | None, typer.Option("--mag-v", help="Johnson V magnitude.")] = None,
    b_v: Annotated[float | None, typer.Option("--b-v", help="B-V colour index.")] = None,
    mag_h: Annotated[float | None, typer.Option("--mag-h", help="2MASS H magnitude.")] = None,
    h_ks: Annotated[float | None, typer.Option("--h-ks", help="2MASS H-Ks colour.")] = None,
    mag: Annotated[
        float | None, typer.Option("--mag", help="Magnitude in --colour's band.")
    ] = None,
    colour_index: Annotated[
        float | None, typer.Option("--colour-index", help="Colour index in --colour.")
    ] = None,
    colour: ColourOpt = None,
    diameter_m: DiameterOpt = 0.1,
    exposure_s: ExposureOpt = 0.1,
    as_json: JsonOpt = False,
) -> None:
    """One star's black body, photons and centroid bound (Table 1; eqs. 9, 12, 19)."""
    check_aperture_options(diameter_m, exposure_s)
    given = [
        names
        for names, values in (
            ("--mag-v/--b-v", (mag_v, b_v)),
            ("--mag-h/--h-ks", (mag_h, h_ks)),
            ("--mag/--colour-index/--colour", (mag, colour_index, colour)),
        )
        if any(v is not None for v in values)
    ]
    if len(given) > 1:  # one star: one magnitude system, never one silently ignored
        raise InputError(f"{' and '.join(given)} both describe the star; give one of them")
    if mag_v is not None or b_v is not None:
        if mag_v is None or b_v is None:
            raise InputError("--mag-v and --b-v must be given together")
        m, ci, system, names = mag_v, b_v, "B-V", ("--mag-v", "--b-v")
    elif mag_h is not None or h_ks is not None:
        if mag_h is None or h_ks is None:
            raise InputError("--mag-h and --h-ks must be given together")
        m, ci, system, names = mag_h, h_ks, "H-Ks", ("--mag-h", "--h-ks")
    elif mag is not None and colour_index is not None and colour is not None:
        m, ci, system, names = mag, colour_index, colour, ("--mag", "--colour-index")
    else:
        raise InputError(
            "give --mag-v and --b-v, or --mag-h and --h-ks, or --mag, --colour-index and --colour"
        )

    option_float(m, names[0], *MAG_RANGE)
    option_float(ci, names[1])
    t, c = fit_star(m, ci, system)
    clamped = colour_clamp_note(system, ci, names[1], t)
    f = float(centroid_fisher(c, t, diameter_m=diameter_m, exposure_s=exposure_s))
    photons = float(total_photons(c, t, diameter_m=diameter_m, exposure_s=exposure_s))
    sigma = 1.0 / np.sqrt(f)
    payload = {
        "temperature_k": t,
        "dilution": c,
        "photons": photons,
        "sigma_rad": float(sigma),
        "sigma_arcsec": float(sigma * RAD_TO_ARCSEC),
        "colour": system,
        "magnitude_band": ColourModel(system).magnitude_band,
        "diameter_m": diameter_m,
        "exposure_s": exposure_s,
        "colour_clamped": clamped is not None,
    }
    if clamped is not None:
        typer.echo(f"warning: {clamped}", err=True)
    emit(
        payload,
        as_json,
        [
            f"black body ({system}): T = {t:.0f} K, C = {c:.3e}",
            f"photons collected (D = {diameter_m} m, t = {exposure_s} s): {photons:.4g}",
            f"centroid bound sigma_min: {_rad(sigma)}",
        ],
    )


@limit_app.command("sky")
def limit_sky(
    diameter_m: DiameterOpt = 1.0,
    exposure_s: ExposureOpt = 1.0,
    catalog: ScaleCatalogOpt = "hipparcos",
    max_mag: Annotated[
        float | None, typer.Option("--max-mag", help="Use only stars brighter than this.")
    ] = None,
    colour: ColourOpt = None,
    fov_deg: Annotated[
        float | None, typer.Option("--fov-deg", help="FOV cone diameter, deg (with --target-deg).")
    ] = None,
    target_deg: Annotated[
        list[str] | None,
        typer.Option("--target-deg", help="RA,DEC of a head's boresight, deg; repeat for heads."),
    ] = None,
    dask: DaskOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Attitude limit over a catalogue: theta_rms, per-axis sigma, G (eqs. 21-24; Table 2).

    With --catalog hats:PATH_OR_URL the catalogue is processed partition by partition on Dask
    (--dask), with the same kernels and results as in memory.
    """
    check_aperture_options(diameter_m, exposure_s)
    if (fov_deg is None) != (not target_deg):
        raise InputError("--fov-deg and --target-deg go together (one or more targets)")
    if fov_deg is not None:
        check_scalar(fov_deg, "--fov-deg", 0, 360, lo_open=True)
    radec = [_parse_target(t) for t in target_deg or []]
    _check_max_mag(max_mag)
    if check_dask_option(catalog, dask):
        _limit_sky_hats(
            catalog, dask, diameter_m, exposure_s, max_mag, colour, fov_deg, radec, as_json
        )
        return

    cat, stars = _load_stars(catalog, max_mag, colour)
    common = {"catalog": cat.name, "colour": stars.colour, "n_skipped": stars.n_skipped}
    if fov_deg is None:
        res = sky_limit(stars, diameter_m=diameter_m, exposure_s=exposure_s)
        payload = {**res.to_dict(), **common}
        lines = [
            f"catalogue {cat.name}: {res.n_stars} stars ({stars.colour}; "
            f"{stars.n_skipped} skipped without magnitude or colour)",
            f"theta_rms (D = {diameter_m} m, t = {exposure_s} s): {_rad(res.theta_rms_rad)}",
            "per-axis sigma (ICRS x, y, z): "
            + ", ".join(f"{s:.3g}" for s in res.axis_sigma_rad)
            + " rad",
            f"G = {res.g_rad_m2_s05:.3e} rad m^2 s^1/2 (paper: 7e-15 < G < 1e-13)",
        ]
        emit(payload, as_json, lines)
        return
    heads, merged = fov_limit(
        stars,
        _target_vectors(radec),
        fov_diameter_rad=fov_deg * DEG,
        diameter_m=diameter_m,
        exposure_s=exposure_s,
    )
    _emit_fov(cat.name, stars.colour, common, fov_deg, radec, heads, merged, as_json)


def _emit_fov(name, colour, common, fov_deg, radec, heads, merged, as_json) -> None:
    best = merged if merged is not None else heads[0]
    payload = {
        **best.to_dict(),
        **common,
        "fov_deg": fov_deg,
        "heads": [
            {"target_deg": list(rd), **h.to_dict()} for rd, h in zip(radec, heads, strict=True)
        ],
    }
    if merged is not None:
        payload["merged"] = merged.to_dict()
    lines = [f"catalogue {name} ({colour}), FOV {fov_deg} deg:"]
    for rd, h in zip(radec, heads, strict=True):
        lines.append(
            f"  head at RA {rd[0]:g}, Dec {rd[1]:g}: {h.n_stars} stars, theta_rms "
            f"{_rad(h.theta_rms_rad)}; cross-boresight {h.axis_sigma_rad[0]:.3g}, "
            f"{h.axis_sigma_rad[1]:.3g} rad, roll {h.axis_sigma_rad[2]:.3g} rad"
        )
    if merged is not None:
        lines.append(f"  merged heads: theta_rms {_rad(merged.theta_rms_rad)}")
    emit(payload, as_json, lines)


def _limit_sky_hats(
    catalog, dask, diameter_m, exposure_s, max_mag, colour, fov_deg, radec, as_json
) -> None:
    """Run ``limit sky`` over a HATS catalogue on Dask (starsense.scale)."""
    with hats_session(catalog, dask, not as_json) as (cat, client, progress):
        opts = {"colour": colour, "max_mag": max_mag, "client": client, "progress": progress}
        if fov_deg is None:
            res, used = hats_sky_limit(cat, diameter_m=diameter_m, exposure_s=exposure_s, **opts)
        else:
            heads, merged, used = hats_fov_limit(
                cat,
                _target_vectors(radec),
                fov_diameter_rad=fov_deg * DEG,
                diameter_m=diameter_m,
                exposure_s=exposure_s,
                **opts,
            )
    common = {
        "catalog": cat.name,
        "colour": used.colour,
        "n_skipped": used.n_skipped,
        "source": cat.location,
    }
    if fov_deg is not None:
        _emit_fov(cat.name, used.colour, common, fov_deg, radec, heads, merged, as_json)
        return
    emit(
        {**res.to_dict(), **common},
        as_json,
        [
            f"HATS catalogue {cat.name} ({cat.location}, {cat.n_partitions} partitions): "
            f"{res.n_stars} stars ({used.colour}; {used.n_skipped} skipped without magnitude or "
            "colour)",
            f"theta_rms (D = {diameter_m} m, t = {exposure_s} s): {_rad(res.theta_rms_rad)}",
            "per-axis sigma (ICRS x, y, z): "
            + ", ".join(f"{s:.3g}" for s in res.axis_sigma_rad)
            + " rad",
            f"G = {res.g_rad_m2_s05:.3e} rad m^2 s^1/2 (paper: 7e-15 < G < 1e-13)",
        ],
    )


@limit_app.command("curve")
def limit_curve(
    catalog: ScaleCatalogOpt = "hipparcos",
    colour: ColourOpt = None,
    diameter_m: DiameterOpt = 1.0,
    exposure_s: ExposureOpt = 1.0,
    extrapolate_to: Annotated[
        float, typer.Option("--extrapolate-to", help="N stars to extrapolate to (paper: 3e11).")
    ] = 3e11,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write a PNG of the curve.", callback=output_file)
    ] = None,
    dask: DaskOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """theta_rms over the N brightest stars, N = 2 .. all, and its extrapolation (Fig. 7).

    With --catalog hats:PATH_OR_URL the curve is built partition by partition on Dask (--dask)
    from magnitude histograms, without sorting the catalogue.
    """
    check_aperture_options(diameter_m, exposure_s)
    # the paper's 3e11 is the Galaxy's stars; 1e308 overflowed the figure's axis (a traceback)
    check_scalar(extrapolate_to, "--extrapolate-to", 2, 1e13)
    if check_dask_option(catalog, dask):
        with hats_session(catalog, dask, not as_json) as (cat, client, progress):
            curve = hats_curve(
                cat,
                diameter_m=diameter_m,
                exposure_s=exposure_s,
                n_extrapolated=extrapolate_to,
                colour=colour,
                client=client,
                progress=progress,
            )
    else:
        cat, stars = _load_stars(catalog, None, colour)
        curve = brightest_curve(
            stars, diameter_m=diameter_m, exposure_s=exposure_s, n_extrapolated=extrapolate_to
        )
    payload = {"catalog": cat.name, "diameter_m": diameter_m, "exposure_s": exposure_s}
    payload.update(curve.to_dict())
    lines = [
        f"catalogue {cat.name} ({curve.colour}), D = {diameter_m} m, t = {exposure_s} s",
        *(
            f"  N = {n:>9d}  theta_rms = {th:.3e} rad"
            for n, th in zip(
                curve.n_stars[:: max(1, len(curve.n_stars) // 12)],
                curve.theta_rms_rad[:: max(1, len(curve.n_stars) // 12)],
                strict=True,
            )
        ),
        f"  all {curve.n_stars[-1]} stars: {curve.theta_rms_rad[-1]:.3e} rad",
        f"  tail slope d log theta / d log N = {curve.slope:.3f}; extrapolated to "
        f"N = {extrapolate_to:.3g}: {curve.theta_extrapolated_rad:.3e} rad",
    ]
    if plot is not None:
        plotting.limits.plot_brightest_curves(
            [curve], plot, catalog_name=cat.name, diameter_m=diameter_m, exposure_s=exposure_s
        )
        payload["plot"] = str(plot)
        lines.append(f"  figure: {plot}")
    emit(payload, as_json, lines)


@limit_app.command("photons")
def limit_photons(
    diameter_m: DiameterOpt = 0.1,
    exposure_s: ExposureOpt = 0.01,
    catalog: CatalogOpt = "hipparcos",
    colour: ColourOpt = None,
    trials: Annotated[int, typer.Option("--trials", help="Monte Carlo draws.")] = 200,
    seed: SeedOpt = 0,
    as_json: JsonOpt = False,
) -> None:
    """Low-photon degradation of the limit for small sensors and short exposures (sec. 3.3.2)."""
    check_count(trials, "--trials", MAX_PHOTON_TRIALS, PHOTON_TRIAL_COST)
    check_aperture_options(diameter_m, exposure_s)
    cat, stars = _load_stars(catalog, None, colour)
    res = low_photon_degradation(
        stars, diameter_m=diameter_m, exposure_s=exposure_s, n_trials=trials, rng=seed
    )
    payload = {"catalog": cat.name, "diameter_m": diameter_m, "exposure_s": exposure_s}
    payload.update(res.to_dict())
    emit(
        payload,
        as_json,
        [
            f"catalogue {cat.name}: {len(stars)} stars, {res.n_below_one_photon} expected to "
            f"deliver < 1 photon; {res.expected_observed_stars:.4g} seen on average",
            f"theta_rms ideal {_rad(res.theta_ideal_rad)}; with Poisson photon counts "
            f"{_rad(res.theta_poisson_rad)} (x{res.degradation:.4f}, {trials} trials)",
            f"D^2 t = {diameter_m**2 * exposure_s:.3g} m^2 s (paper: >= 1e-4 comes close to "
            "the limit)",
        ],
    )
