"""The trade's output keys: each row's name with its unit, for JSON lines and CSV columns.

The trade rows are the datasheet comparison's (:data:`~starsense.analysis.datasheet.compare.
ROW_KEYS`, also the keys of :attr:`TradeRow.rows <starsense.analysis.trade.study.TradeRow>`);
what ``starsense trade`` writes (``--json``, ``--csv``, ``trade.jsonl``, ``trade.csv``) names
them with their unit, so a program reading the file needs no table of units:
``nea_cross_arcsec``, ``fastest_rate_99pct_deg_s``, ``lis_solved_fraction_rest``. A ratio or a
count says so (``measured_over_predicted_cross``, ``lis_wrong_count_rest``); a magnitude is V.
"""

from __future__ import annotations

__all__ = ["OUTPUT_KEYS", "named_rows"]

#: trade row key -> its name in the trade's output (with its unit)
OUTPUT_KEYS: dict[str, str] = {
    "fov_width_deg": "fov_width_deg",
    "fov_height_deg": "fov_height_deg",
    "pixel_scale_arcsec": "pixel_scale_arcsec",
    "limiting_magnitude": "limiting_magnitude_v",
    "stars_median": "stars_in_field_median_count",
    "nea_cross": "nea_cross_arcsec",
    "nea_roll": "nea_roll_arcsec",
    "nea_cross_measured": "nea_cross_measured_arcsec",
    "nea_roll_measured": "nea_roll_measured_arcsec",
    "limit_cross": "limit_cross_arcsec",
    "limit_roll": "limit_roll_arcsec",
    "nea_over_limit_cross": "nea_over_limit_cross_ratio",
    "nea_over_limit_roll": "nea_over_limit_roll_ratio",
    "lis_solved_rest": "lis_solved_fraction_rest",
    "lis_wrong_rest": "lis_wrong_count_rest",
    "lis_ms_rest": "lis_median_time_ms_rest",
    "lis_solved_rate": "lis_solved_fraction_rate",
    "lis_wrong_rate": "lis_wrong_count_rate",
    "lis_ms_rate": "lis_median_time_ms_rate",
    "ratio_cross": "measured_over_predicted_cross",
    "ratio_roll": "measured_over_predicted_roll",
    "fastest_50": "fastest_rate_50pct_deg_s",
    "fastest_90": "fastest_rate_90pct_deg_s",
    "fastest_99": "fastest_rate_99pct_deg_s",
    "availability_lis_rest": "availability_lis_fraction_rest",
    "availability_lis_0.5": "availability_lis_fraction_at_0.5_deg_s",
    "availability_lis_1": "availability_lis_fraction_at_1_deg_s",
    "availability_lis_2": "availability_lis_fraction_at_2_deg_s",
    "availability_lis_rate": "availability_lis_fraction_at_rate",
    "budget_total_cross": "budget_total_cross_arcsec",
    "budget_total_roll": "budget_total_roll_arcsec",
    **{
        f"ecss_total_{a}_{where}": f"ecss_total_{a}_arcsec_{suffix}"
        for where, suffix in (("rest", "rest"), ("rate", "at_rate"))
        for a in ("x", "y", "z")
    },
}


def named_rows(rows: dict | None) -> dict | None:
    """Return trade rows keyed by their output names (:data:`OUTPUT_KEYS`), in order.

    Parameters
    ----------
    rows : dict or None
        ``{row key: {"value", "capped"}}``
        (:func:`~starsense.analysis.datasheet.compare.row_values`).

    Returns
    -------
    dict or None
        The same entries under their output names; None for None (a design in error).
    """
    if rows is None:
        return None
    return {OUTPUT_KEYS[k]: v for k, v in rows.items()}
