"""A small reference summation of the ECSS statement's CSV, from its rows alone."""

from __future__ import annotations

import csv
import io
import math

import pytest


def assert_totals_are_the_rows_sums(text: str, rates: tuple[str, ...]) -> dict:
    """Check each rate's and axis's totals against the root sum squares of the counted rows,
    split by what each acts as at that rate; return the total rows by name."""
    rows = list(csv.DictReader(io.StringIO(text)))
    terms = [r for r in rows if not r["term"].startswith("total")]
    totals = {r["term"]: r for r in rows if r["term"].startswith("total")}
    for lab in rates:
        for a in "xyz":
            col = f"{a}_arcsec_at_{lab}_deg_s"
            sums = {"bias": 0.0, "noise": 0.0}
            for r in terms:
                if r["counted"] == "true" and r[col] != "":
                    sums[r[f"acts_as_at_{lab}_deg_s"]] += float(r[col]) ** 2
            for name, s in (("total_bias", sums["bias"]), ("total_noise", sums["noise"])):
                assert float(totals[name][col]) == pytest.approx(math.sqrt(s), rel=1e-12)
            whole = math.sqrt(sums["bias"] + sums["noise"])
            assert float(totals["total"][col]) == pytest.approx(whole, rel=1e-12)
    return totals
