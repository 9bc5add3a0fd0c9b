"""Compiled kernels shared by the pure-Python agents (Numba, cached on disk)."""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["borrowed", "nearest_index", "scaled_distance"]


@intrinsic
def borrowed(typingctx, arr):
    """A view of ``arr`` that does not own a reference to its memory.

    Numba counts references to an array with atomic increments and decrements each
    time the array is handed on, and in a hot loop that passes a dozen state arrays
    around, those atomics cost about a third of the time. A borrowed view has no
    memory-info block, so counting it is a null check. The caller must keep ``arr``
    alive while the view is used: the fused loops borrow their arguments, which the
    Python caller holds, and never return the views.
    """
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        src = context.make_array(arr)(context, builder, value=args[0])
        view = context.make_array(arr)(context, builder)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(view, field, getattr(src, field))
        view.meminfo = context.get_constant_null(types.MemInfoPointer(arr.dtype))
        view.parent = context.get_constant_null(types.pyobject)
        return view._getvalue()

    return arr(arr), codegen


@njit(cache=True, inline="always")
def scaled_distance(V: np.ndarray, i: int, x: np.ndarray, inv_scale: np.ndarray) -> float:
    """Scaled distance between vector ``V[i]`` and the point ``x``."""
    s = 0.0
    for d in range(x.shape[0]):
        z = (V[i, d] - x[d]) * inv_scale[d]
        s += z * z
    return np.sqrt(s)


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


@njit(cache=True, nogil=True)
def nearest_batch_kernel(vectors: np.ndarray, size: int, xs: np.ndarray, inv_scale: np.ndarray,
                         cand: np.ndarray) -> np.ndarray:
    """:func:`nearest_index` of every row of ``xs``, with the very same arithmetic (so that a batch query and
    the agent's own step agree on every tie). ``cand`` ``(b, k)``: look only among these candidates
    (``k = 0``: among all ``size`` vectors); lowest index on ties among them."""
    out = np.empty(xs.shape[0], dtype=np.int64)
    n = xs.shape[1]
    for q in range(xs.shape[0]):
        if cand.shape[1] == 0:
            out[q], _ = nearest_index(vectors, size, xs[q], inv_scale)
            continue
        best = size
        best_d2 = np.inf
        for c in range(cand.shape[1]):
            k = cand[q, c]
            s = 0.0
            for d in range(n):
                z = (vectors[k, d] - xs[q, d]) * inv_scale[d]
                s += z * z
            if s < best_d2 or (s == best_d2 and k < best):
                best_d2 = s
                best = k
        out[q] = best
    return out


@njit(cache=True, nogil=True)
def neighbours_kernel(vectors: np.ndarray, size: int, inv_scale: np.ndarray):
    """For each of the first ``size`` vectors: nearest other (lowest index on ties), its distance,
    and the second-smallest distance (equal to the first when the nearest is not unique)."""
    n = vectors.shape[1]
    y = np.empty((size, n))
    for k in range(size):
        for d in range(n):
            y[k, d] = vectors[k, d] * inv_scale[d]
    nn = np.full(size, -1, dtype=np.int64)
    d1 = np.full(size, np.inf)
    d2 = np.full(size, np.inf)
    for i in range(size):
        for j in range(size):
            if j == i:
                continue
            s = 0.0
            for d in range(n):
                z = y[i, d] - y[j, d]
                s += z * z
            dist = np.sqrt(s)
            if dist < d1[i]:
                d2[i] = d1[i]
                d1[i] = dist
                nn[i] = j
            elif dist < d2[i]:
                d2[i] = dist
    return nn, d1, d2


@njit(cache=True, nogil=True)
def mutual_nearest_pairs_kernel(vectors: np.ndarray, size: int, inv_scale: np.ndarray,
                                strict: bool = True) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, each the other's unique nearest vector (SPEC §4, Fig. 2's strict <).

    With ``strict=False`` a tie for the nearest goes to the lowest index instead of
    blocking the pair (beyond the paper: on integer grids, ties are common).
    """
    nn, d1, d2 = neighbours_kernel(vectors, size, inv_scale)
    count = 0
    for i in range(size):
        j = nn[i]
        if j > i and nn[j] == i and (not strict or (d1[i] < d2[i] and d1[j] < d2[j])):
            count += 1
    out = np.empty((count, 2), dtype=np.int64)
    k = 0
    for i in range(size):
        j = nn[i]
        if j > i and nn[j] == i and (not strict or (d1[i] < d2[i] and d1[j] < d2[j])):
            out[k, 0] = i
            out[k, 1] = j
            k += 1
    return out


@njit(cache=True, nogil=True)
def nearest_pairs_kernel(vectors: np.ndarray, size: int, inv_scale: np.ndarray) -> np.ndarray:
    """Disjoint pairs ``(i, nearest of i)``, closest first, mutual or not (``i < j`` in each pair)."""
    nn, d1, _ = neighbours_kernel(vectors, size, inv_scale)
    order = np.argsort(d1[:size], kind="mergesort")
    used = np.zeros(size, dtype=np.bool_)
    out = np.empty((size // 2, 2), dtype=np.int64)
    k = 0
    for t in range(size):
        i = order[t]
        j = nn[i]
        if j < 0 or used[i] or used[j]:
            continue
        used[i] = True
        used[j] = True
        out[k, 0] = min(i, j)
        out[k, 1] = max(i, j)
        k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def merge_kernel(vectors: np.ndarray, size: int, pairs: np.ndarray) -> np.ndarray:
    """Replace each disjoint pair ``(i, j)``, ``i < j``, by its midpoint in slot ``i``; drop slot ``j``
    and move later vectors down. Returns ``mapping[old] = new`` (both members map to one index)."""
    n = vectors.shape[1]
    removed = np.zeros(size, dtype=np.bool_)
    partner = np.full(size, -1, dtype=np.int64)
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        for d in range(n):
            vectors[i, d] = (vectors[i, d] + vectors[j, d]) / 2.0
        removed[j] = True
        partner[j] = i
    mapping = np.empty(size, dtype=np.int64)
    w = 0
    for r in range(size):
        if not removed[r]:
            mapping[r] = w
            if w != r:
                vectors[w, :] = vectors[r, :]
            w += 1
    for r in range(size):
        if removed[r]:
            mapping[r] = mapping[partner[r]]
    return mapping


@njit(cache=True, nogil=True)
def compact_rows(values: np.ndarray, mapping: np.ndarray) -> int:
    """Move each kept row ``r`` (the first old row of each new index) to ``mapping[r]``; return the new count."""
    nxt = 0
    for r in range(mapping.shape[0]):
        if mapping[r] == nxt:
            if nxt != r:
                values[nxt] = values[r]
            nxt += 1
    return nxt
