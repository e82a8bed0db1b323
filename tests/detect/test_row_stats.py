"""row_nanmedian against NumPy's nanmedian: the same values, NaN rows included."""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from starsense.detect.row_stats import row_nanmedian


@settings(max_examples=300, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    rows=st.integers(1, 8),
    cols=st.integers(1, 200),
    nan_fraction=st.sampled_from([0.0, 0.3, 0.9, 1.0]),
)
def test_row_nanmedian_is_numpys(seed, rows, cols, nan_fraction):
    rng = np.random.default_rng(seed)
    a = rng.normal(1000.0, 50.0, (rows, cols)).round()  # counts: ties among them
    a[rng.random((rows, cols)) < nan_fraction] = np.nan
    with warnings.catch_warnings():  # NumPy warns on an all-NaN row; row_nanmedian does not
        warnings.simplefilter("ignore", RuntimeWarning)
        want = np.nanmedian(a, axis=1)
    # the same middle values and the same mean of two: equal bit for bit
    np.testing.assert_array_equal(row_nanmedian(a), want)
