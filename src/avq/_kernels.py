"""Compiled kernels shared by the pure-Python agents (Numba, cached on disk)."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["nearest_index"]


@njit(cache=True, nogil=True)
def nearest_index(vectors: np.ndarray, size: int, x: np.ndarray, inv_scale: np.ndarray) -> tuple[int, float]:
    """Brute-force nearest of the first ``size`` rows to ``x``: (index, squared scaled distance).

    Lowest index on ties (strict ``<``), like ``numpy.argmin``.
    """
    best = 0
    best_d2 = np.inf
    n = x.shape[0]
    for k in range(size):
        s = 0.0
        for d in range(n):
            z = (vectors[k, d] - x[d]) * inv_scale[d]
            s += z * z
        if s < best_d2:
            best_d2 = s
            best = k
    return best, best_d2
