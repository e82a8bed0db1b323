"""Work buffers kept from one call to the next: no allocation per frame or per fit.

A frame's detection passes through several whole-frame float32 arrays (the subtracted frame,
the filter's passes, the thresholds, the labels). Allocated afresh for every frame, each is
new memory that the operating system maps page by page on first touch: ~2,300 page faults and
~6 ms per 768 x 1024 frame, a fifth of the detection. Flight software allocates its frame
buffers once; :func:`scratch` does the same per thread, one buffer per name and shape, reused
from frame to frame. Only internal temporaries use it: nothing returned to a caller
is a scratch buffer. Frames above :data:`MAX_KEPT_PIXELS` are not kept (their buffers are
allocated per frame, as before), so that a few huge frames do not pin hundreds of MB. The
forward model's fit lays its arrays out in one such buffer (:mod:`starsense.model.problem`), of
a power-of-two length so that fits of other sizes reuse it.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict

import numpy as np

__all__ = ["MAX_KEPT_BUFFERS", "MAX_KEPT_PIXELS", "scratch"]

#: frames up to this many pixels keep their buffers (8.4 Mpx: 34 MB per float32 buffer; the
#: ST-16's 5 Mpx frames keep ~70 MB per thread with the matched filter, ~20 MB without)
MAX_KEPT_PIXELS = 1 << 23
#: buffers kept per thread (the least recently used beyond this are let go)
MAX_KEPT_BUFFERS = 32

_LOCAL = threading.local()


def scratch(name: str, shape: tuple[int, ...], dtype=np.float32) -> np.ndarray:
    """Return this thread's buffer ``name`` of ``shape`` and ``dtype`` (contents undefined).

    Parameters
    ----------
    name : str
        What the buffer holds; two temporaries alive at once need two names.
    shape : tuple of int
    dtype : numpy dtype

    Returns
    -------
    ndarray
        The array of the last call with this name, shape and dtype in this thread, or a new
        one (always new above :data:`MAX_KEPT_PIXELS` elements).
    """
    dtype = np.dtype(dtype)
    shape = tuple(int(n) for n in shape)
    if math.prod(shape) > MAX_KEPT_PIXELS:
        return np.empty(shape, dtype)
    buffers = getattr(_LOCAL, "buffers", None)
    if buffers is None:
        buffers = _LOCAL.buffers = OrderedDict()
    key = (name, shape, dtype.str)
    buf = buffers.get(key)
    if buf is None:
        buf = buffers[key] = np.empty(shape, dtype)
        while len(buffers) > MAX_KEPT_BUFFERS:
            buffers.popitem(last=False)
    else:
        buffers.move_to_end(key)
    return buf
