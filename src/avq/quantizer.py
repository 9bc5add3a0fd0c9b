"""The codebook: a nearest-neighbour vector quantizer that can grow and merge.

Geometry only (SPEC §1, §3, §4). The codebook knows its vectors, the metric,
nearest-vector queries, appends and pairwise merges. It holds no values: every
operation that changes indices hands back the index mapping, and the agent
applies that mapping to its own arrays.

The metric is the Euclidean distance after dividing each dimension by its
scale ``s`` (SPEC §1)::

    dist(x, y) = || (x - y) / s ||
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from avq._kernels import merge_kernel, mutual_nearest_pairs_kernel, nearest_batch_kernel, nearest_index, neighbours_kernel

__all__ = ["Codebook"]

# Above this many vectors, pairwise work uses a k-d tree instead of a dense matrix.
_TREE_THRESHOLD = 512


class Codebook:
    """A growing set of codebook vectors ``y_1 .. y_p`` in ``R^n``.

    Args:
        n_dims: Dimension ``n`` of the vectors.
        scale: Per-dimension scale ``s`` (> 0), a scalar or a length-``n`` sequence.
        capacity: Initial preallocated number of vectors; storage doubles when full.

    Vectors are stored in a preallocated ``(capacity, n)`` array; :attr:`vectors`
    is a view of the first :attr:`size` rows.
    """

    def __init__(self, n_dims: int, scale: float | Sequence[float] | np.ndarray = 1.0, capacity: int = 64) -> None:
        if int(n_dims) < 1:
            raise ValueError(f"n_dims must be >= 1, not {n_dims}")
        self.n_dims = int(n_dims)
        s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (self.n_dims,)).copy()
        if not np.all(np.isfinite(s)) or np.any(s <= 0):
            raise ValueError(f"scale must be finite and > 0 in every dimension, not {s.tolist()}")
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
        """Pairs ``(i, j)``, ``i < j``, that are each other's unique nearest vector (SPEC §4).

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
        self._data[self.size] = x
        self.size += 1
        return self.size - 1

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
    def from_vectors(cls, vectors: np.ndarray, scale: float | Sequence[float] | np.ndarray = 1.0) -> "Codebook":
        """A codebook holding a copy of ``vectors`` (``(p, n)``)."""
        vectors = np.asarray(vectors, dtype=np.float64)
        cb = cls(vectors.shape[1], scale, capacity=max(len(vectors), 1))
        cb._data[: len(vectors)] = vectors
        cb.size = len(vectors)
        return cb
