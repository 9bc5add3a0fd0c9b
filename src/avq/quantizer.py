"""The codebook: a nearest-neighbour vector quantizer that can grow and merge.

Geometry only (docs/explanation/paper.md#setting, #growing, #merging). The codebook knows its vectors, the metric,
nearest-vector queries, appends and pairwise merges. It holds no values: every
operation that changes indices hands back the index mapping, and the agent
applies that mapping to its own arrays.

Two faces of one geometry: compiled functions on a preallocated ``(capacity, n)`` array and a
count of rows in use (:func:`nearest_index`, :func:`append_vector`, :func:`merge_kernel`, the pair
searches), which the agents' kernels call inside their compiled loops; and :class:`Codebook`, the
same functions behind a Python object, for queries and for tests.

The metric is the Euclidean distance after dividing each dimension by its
scale ``s`` (docs/explanation/paper.md#setting)::

    dist(x, y) = || (x - y) / s ||
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

__all__ = [
    "Codebook",
    "append_vector",
    "compact_rows",
    "merge_kernel",
    "mutual_nearest_pairs_kernel",
    "nearest_batch_kernel",
    "nearest_index",
    "nearest_pairs_kernel",
    "neighbours_kernel",
    "scaled_distance",
]

# Above this many vectors, pairwise work uses a k-d tree instead of a dense matrix.
_TREE_THRESHOLD = 512


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
def nearest_batch_kernel(
    vectors: np.ndarray, size: int, xs: np.ndarray, inv_scale: np.ndarray, cand: np.ndarray
) -> np.ndarray:
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
    # Each distance once, for both ends of the pair (the difference negated squares to the same sum): each
    # vector meets the others in increasing order of index, vector i those before it while they run here.
    for i in range(size):
        nn_i, d1_i, d2_i = nn[i], d1[i], d2[i]
        for j in range(i + 1, size):
            s = 0.0
            for d in range(n):
                z = y[i, d] - y[j, d]
                s += z * z
            dist = np.sqrt(s)
            if dist < d1_i:
                d2_i = d1_i
                d1_i = dist
                nn_i = j
            elif dist < d2_i:
                d2_i = dist
            if dist < d1[j]:
                d2[j] = d1[j]
                d1[j] = dist
                nn[j] = i
            elif dist < d2[j]:
                d2[j] = dist
        nn[i], d1[i], d2[i] = nn_i, d1_i, d2_i
    return nn, d1, d2


@njit(cache=True, nogil=True)
def mutual_nearest_pairs_kernel(
    vectors: np.ndarray, size: int, inv_scale: np.ndarray, strict: bool = True
) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, each the other's unique nearest vector (docs/explanation/paper.md#merging, Fig. 2's strict <).

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
def _stable_order(values: np.ndarray) -> np.ndarray:
    """``np.argsort(values, kind="mergesort")`` (ascending, ties in index order) for values without NaN; by
    insertion up to 64 values (a merge pass sorts a few dozen distances, for which a merge sort costs more)."""
    if values.shape[0] > 64:
        return np.argsort(values, kind="mergesort")
    order = np.empty(values.shape[0], dtype=np.int64)
    for k in range(values.shape[0]):
        v = values[k]
        w = k
        while w > 0 and v < values[order[w - 1]]:
            order[w] = order[w - 1]
            w -= 1
        order[w] = k
    return order


@njit(cache=True, nogil=True)
def nearest_pairs_kernel(vectors: np.ndarray, size: int, inv_scale: np.ndarray) -> np.ndarray:
    """Disjoint pairs ``(i, nearest of i)``, closest first, mutual or not (``i < j`` in each pair)."""
    nn, d1, _ = neighbours_kernel(vectors, size, inv_scale)
    return disjoint_pairs(nn, d1[:size])


@njit(cache=True, nogil=True)
def disjoint_pairs(partner: np.ndarray, score: np.ndarray) -> np.ndarray:
    """Disjoint pairs ``(i, partner[i])`` (``-1``: none), lowest ``score[i]`` first (ties by index), each cell in
    one pair at most, written ``i < j``."""
    size = score.shape[0]
    order = _stable_order(score)
    used = np.zeros(size, dtype=np.bool_)
    out = np.empty((size // 2, 2), dtype=np.int64)
    k = 0
    for t in range(size):
        i = order[t]
        j = partner[i]
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


@njit(cache=True, inline="always")
def append_vector(vectors: np.ndarray, size: int, x: np.ndarray) -> int:
    """Write ``x`` into row ``size`` (the first free one) and return that index; the caller counts the new size.
    Every codebook append, the agents' and :meth:`Codebook.append`, goes through here."""
    # Element loops, not slices: slice assignment drags shape-error formatting into the hot path.
    for d in range(x.shape[0]):
        vectors[size, d] = x[d]
    return size


class Codebook:
    """A growing set of codebook vectors ``y_1 .. y_p`` in ``R^n``.

    Args:
        n_dims: Dimension ``n`` of the vectors.
        scale: Per-dimension scale ``s`` (> 0; ``inf`` ignores the dimension), a scalar or a length-``n`` sequence.
        capacity: Initial preallocated number of vectors; storage doubles when full.

    Vectors are stored in a preallocated ``(capacity, n)`` array; :attr:`vectors`
    is a view of the first :attr:`size` rows.
    """

    def __init__(self, n_dims: int, scale: float | Sequence[float] | np.ndarray = 1.0, capacity: int = 64) -> None:
        if int(n_dims) < 1:
            raise ValueError(f"n_dims must be >= 1, not {n_dims}")
        self.n_dims = int(n_dims)
        s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (self.n_dims,)).copy()
        if np.any(np.isnan(s)) or np.any(s <= 0):
            raise ValueError(f"scale must be > 0 in every dimension (inf: ignored), not {s.tolist()}")
        self.scale = s
        self.inv_scale = 1.0 / s
        self._data = np.zeros((max(int(capacity), 1), self.n_dims), dtype=np.float64)
        self.size = 0

    # -- queries -------------------------------------------------------------------
    @property
    def vectors(self) -> np.ndarray:
        """The codebook, ``(size, n)`` (a view: do not modify)."""
        return self._data[: self.size]

    def __len__(self) -> int:
        return self.size

    def distance(self, i: int, x: np.ndarray) -> float:
        """Scaled distance between vector ``i`` and point ``x``."""
        d = (self._data[i] - x) * self.inv_scale
        return float(np.sqrt(d @ d))

    def nearest(self, x: np.ndarray) -> tuple[int, float]:
        """Index of the nearest vector to ``x`` (lowest index on ties) and its scaled distance."""
        if self.size == 0:
            raise ValueError("the codebook is empty")
        i, d2 = nearest_index(self._data, self.size, x, self.inv_scale)
        return int(i), float(np.sqrt(d2))

    def nearest_batch(self, xs: np.ndarray) -> np.ndarray:
        """Nearest-vector indices for each row of ``xs`` (``(b, n)``): what :meth:`nearest` gives for each,
        ties included (the same arithmetic as the agents' compiled steps)."""
        xs = np.ascontiguousarray(np.asarray(xs, dtype=np.float64).reshape(-1, self.n_dims))
        if self.size == 0:
            raise ValueError("the codebook is empty")
        if self.size <= _TREE_THRESHOLD:
            return nearest_batch_kernel(self._data, self.size, xs, self.inv_scale, np.zeros((len(xs), 0), np.int64))
        from scipy.spatial import cKDTree

        # The tree finds the nearest few; exact distances among them then pick the lowest index on
        # ties, as nearest() does. A query whose candidates all tie may tie with more: brute force.
        k = min(4, self.size)
        tree = cKDTree(self.vectors * self.inv_scale)
        d_tree, cand = tree.query(xs * self.inv_scale, k=k)
        cand = np.asarray(cand, dtype=np.int64).reshape(len(xs), k)
        out = nearest_batch_kernel(self._data, self.size, xs, self.inv_scale, cand)
        d_tree = np.asarray(d_tree).reshape(len(xs), k)
        for q in np.flatnonzero(np.isclose(d_tree[:, 0], d_tree[:, -1], rtol=1e-9, atol=0.0)):
            out[q] = self.nearest(xs[q])[0]
        return out

    def neighbours(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For every vector: its nearest other vector, that distance, and the second-nearest distance.

        Returns ``(nn, d1, d2)``; with a single vector, ``nn`` is ``[-1]`` and distances are inf.
        """
        p = self.size
        if p < 2:
            return np.full(p, -1, np.int64), np.full(p, np.inf), np.full(p, np.inf)
        y = self.vectors * self.inv_scale
        k = min(3, p)
        if p > _TREE_THRESHOLD:
            from scipy.spatial import cKDTree

            dist, idx = cKDTree(y).query(y, k=k)
            # Column 0 is the point itself (distance 0) unless duplicates exist; drop self explicitly.
            nn = np.empty(p, np.int64)
            d1 = np.empty(p)
            d2 = np.full(p, np.inf)
            rows = np.arange(p)
            for r in range(p):
                others = [(dist[r, c], idx[r, c]) for c in range(k) if idx[r, c] != rows[r]]
                nn[r], d1[r] = others[0][1], others[0][0]
                if len(others) > 1:
                    d2[r] = others[1][0]
            return nn, d1, d2
        return neighbours_kernel(self._data, p, self.inv_scale)

    def mutual_nearest_pairs(self) -> np.ndarray:
        """Pairs ``(i, j)``, ``i < j``, that are each other's unique nearest vector (docs/explanation/paper.md#merging).

        "Unique" follows Fig. 2 of the paper: ``||y_i - y_j|| < ||y_i - y_h||`` for every
        other ``h``, strictly, and the same from ``j``. A vector with two equally near
        neighbours has no nearest neighbour in this sense and is not merged. The pairs are
        disjoint because each vector has at most one unique nearest neighbour.
        """
        if self.size <= _TREE_THRESHOLD:
            return mutual_nearest_pairs_kernel(self._data, self.size, self.inv_scale)
        nn, d1, d2 = self.neighbours()
        i = np.arange(self.size)
        unique = d1 < d2
        mutual = unique & (nn > i) & unique[nn] & (nn[nn] == i)
        return np.stack([i[mutual], nn[mutual]], axis=1).astype(np.int64)

    # -- changes -------------------------------------------------------------------
    def append(self, x: np.ndarray) -> int:
        """Append ``x`` as a new vector and return its index (``size - 1``)."""
        if self.size == len(self._data):
            self._grow()
        c = append_vector(self._data, self.size, np.asarray(x, dtype=np.float64).reshape(self.n_dims))
        self.size += 1
        return c

    def merge(self, pairs: np.ndarray | Sequence[tuple[int, int]]) -> np.ndarray:
        """Replace each disjoint pair ``(i, j)`` by its midpoint ``(y_i + y_j) / 2``.

        The merged vector takes the lower index's slot; the higher slot is removed and
        later vectors move down, keeping their order.

        Returns:
            ``mapping``: int array of the old size; ``mapping[old]`` is the new index.
            Both members of a pair map to the same new index.
        """
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        p = self.size
        if pairs.size and (pairs.min() < 0 or pairs.max() >= p or np.any(pairs[:, 0] == pairs[:, 1])):
            raise ValueError(f"merge pairs must hold distinct indices in [0, {p})")
        flat = pairs.ravel()
        if len(np.unique(flat)) != len(flat):
            raise ValueError("merge pairs must be disjoint")
        ordered = np.sort(pairs, axis=1)
        mapping = merge_kernel(self._data, p, ordered)
        self.size = p - len(ordered)
        return mapping

    def _grow(self) -> None:
        data = np.zeros((2 * len(self._data), self.n_dims), dtype=np.float64)
        data[: self.size] = self._data[: self.size]
        self._data = data

    @classmethod
    def from_vectors(cls, vectors: np.ndarray, scale: float | Sequence[float] | np.ndarray = 1.0) -> Codebook:
        """A codebook holding a copy of ``vectors`` (``(p, n)``)."""
        vectors = np.asarray(vectors, dtype=np.float64)
        cb = cls(vectors.shape[1], scale, capacity=max(len(vectors), 1))
        cb._data[: len(vectors)] = vectors
        cb.size = len(vectors)
        return cb
