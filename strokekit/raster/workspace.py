"""The z-buffer's buffers reused from frame to frame (`Workspace`), numpy only: a frame task
holds one before the raster kernels have loaded (`raster.hits.thread_workspace`), so its lines
need not wait for them."""

from __future__ import annotations

import numpy as np


class Workspace:
    """Buffers reused from frame to frame: pass the same one to every call to skip allocating
    (and first-touching) ~80 MB a frame at 2 x 2 and 1024 x 1024. The arrays a call returns
    with a workspace are its buffers: the next call of the same kind (grid, or pixels) with it
    overwrites them: copy what you keep. One workspace per thread."""

    def __init__(self):
        self._bufs: dict = {}

    def get(self, name: str, shape: tuple, dtype) -> np.ndarray:
        a = self._bufs.get(name)
        if a is None or a.shape != tuple(shape) or a.dtype != np.dtype(dtype):
            a = np.empty(shape, dtype)
            self._bufs[name] = a
        return a
