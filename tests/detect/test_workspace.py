"""Work buffers (starsense._workspace): reused per name and shape, per thread, bounded."""

from __future__ import annotations

import threading

import numpy as np

from starsense import _workspace as workspace
from starsense._workspace import MAX_KEPT_BUFFERS, MAX_KEPT_PIXELS, scratch
from starsense.detect import StarDetector


def test_same_name_and_shape_is_the_same_buffer():
    a = scratch("test_a", (30, 40))
    assert a.shape == (30, 40) and a.dtype == np.float32
    assert scratch("test_a", (30, 40)) is a
    assert scratch("test_a", (30, 40), bool) is not a  # another dtype, another buffer
    assert scratch("test_a", (31, 40)) is not a  # another shape
    assert scratch("test_b", (30, 40)) is not a  # another name


def test_oldest_buffers_are_let_go():
    first = scratch("test_first", (5, 5))
    for i in range(MAX_KEPT_BUFFERS):
        scratch(f"test_fill_{i}", (5, 5))
    assert len(workspace._LOCAL.buffers) <= MAX_KEPT_BUFFERS
    assert scratch("test_first", (5, 5)) is not first


def test_huge_frames_are_not_kept():
    n = MAX_KEPT_PIXELS + 1
    assert scratch("test_huge", (n,), np.uint8) is not scratch("test_huge", (n,), np.uint8)


def test_each_thread_has_its_own_buffers():
    mine = scratch("test_thread", (4, 4))
    theirs = []
    t = threading.Thread(target=lambda: theirs.append(scratch("test_thread", (4, 4))))
    t.start()
    t.join()
    assert theirs[0] is not mine


def test_detections_do_not_change_when_buffers_are_reused():
    # the same frame twice, with another frame in between: identical detections (nothing left
    # over in a reused buffer changes a result)
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:120, 0:160]
    frame = 100.0 + rng.normal(0, 3, (120, 160))
    for x0, y0 in [(30.2, 40.7), (100.5, 80.1), (140.0, 20.3)]:
        frame += 400 * np.exp(-((xx - x0) ** 2 + (yy - y0) ** 2) / 2.0)
    other = 500.0 + rng.normal(0, 30, (120, 160))
    det = StarDetector(
        background="auto", threshold_sigma=5, matched_filter=True, min_snr=5, psf_sigma_px=1.0
    )
    first = det(frame)
    det(other)
    again = det(frame)
    assert len(first) == 3
    for name in ("x", "y", "integrated_counts", "peak_counts", "bbox"):
        assert np.array_equal(getattr(first, name), getattr(again, name)), name
