"""Background subtraction and threshold search (``starsense.detect.subtract``), kernel and NumPy.

The compiled kernel subtracts in float32 and compares in float32 as NumPy does, so the frame
and the indices must be equal, bit for bit: no tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from starsense.detect import subtract

needs_kernel = pytest.mark.skipif(subtract._framec is None, reason="compiled kernel not built")


def _frame(seed: int, dtype, lit: float):
    """A frame of a camera's sample type, a float32 level map, a fraction ``lit`` far above."""
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(1, 90)), int(rng.integers(1, 700)))
    level = rng.uniform(0, 200, shape).astype(np.float32)
    frame = level + rng.normal(0, 10, shape)
    frame[rng.random(shape) < lit] += rng.uniform(50, 1e4)
    if np.dtype(dtype).kind in "iu":
        info = np.iinfo(dtype)
        frame = np.clip(np.round(frame), info.min, info.max)
    frame = frame.astype(dtype)
    if rng.random() < 0.3:
        frame = frame[:, ::-1]  # not contiguous: copied for the kernel
    return frame, level


@needs_kernel
@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    dtype=st.sampled_from([np.uint8, np.uint16, np.int16, np.int32, np.float32, np.float64]),
    lit=st.sampled_from([0.0, 0.01, 0.2, 1.0]),
    threshold=st.sampled_from([None, 25.0, -1e9, np.inf]),
)
def test_kernel_subtraction_and_search_equal_numpy(seed, dtype, lit, threshold):
    # a fifth of the pixels above (lit = 0.2) overflows the kernel's list on large frames:
    # NumPy's search then takes over, with the same result
    with pytest.MonkeyPatch.context() as m:
        m.setattr(subtract, "_MIN_CAPACITY", 64)
        _check_equal(*_frame(seed, dtype, lit), threshold)


def _check_equal(frame, level, threshold):
    above = None if threshold is None else np.float32(threshold)
    out, idx = subtract.subtract_level(frame, level, np.empty(frame.shape, np.float32), above=above)
    expected = np.subtract(frame, level, dtype=np.float32)
    np.testing.assert_array_equal(out, expected)
    if above is None:
        assert idx is None
        return
    np.testing.assert_array_equal(idx, np.flatnonzero(expected > above))
    np.testing.assert_array_equal(subtract.pixels_above(out, above), idx)
    with pytest.MonkeyPatch.context() as m:  # the NumPy forms, where the kernel is not built
        m.setattr(subtract, "_framec", None)
        out2, idx2 = subtract.subtract_level(frame, level, np.empty_like(out), above=above)
        np.testing.assert_array_equal(out2, expected)
        np.testing.assert_array_equal(idx2, idx)
        np.testing.assert_array_equal(subtract.pixels_above(out, above), idx)


def test_nan_is_never_above_and_a_flat_level_broadcasts():
    frame = np.array([[1.0, np.nan, 5.0]], np.float32)
    out, idx = subtract.subtract_level(
        frame, 2.0, np.empty((1, 3), np.float32), above=np.float32(0)
    )
    np.testing.assert_array_equal(out, [[-1.0, np.nan, 3.0]])
    assert idx.tolist() == [2]
    assert subtract.pixels_above(out, np.float32(-5)).tolist() == [0, 2]


@needs_kernel
def test_kernel_refuses_an_unknown_sample_type_and_short_buffers():
    idx = np.empty(4, np.int64)
    with pytest.raises(ValueError, match="kind q is not one of"):
        subtract._framec.subtract(
            np.zeros(4), "q", np.zeros(4, np.float32), 4, np.empty(4, np.float32), 0.0, idx, 4
        )
    with pytest.raises(ValueError, match="level: buffer of 8 bytes, 16 needed"):
        subtract._framec.subtract(
            np.zeros(4), "d", np.zeros(2, np.float32), 4, np.empty(4, np.float32), 0.0, idx, 4
        )
