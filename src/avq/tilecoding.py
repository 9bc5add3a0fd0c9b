"""Tile coding as in Sutton's ``tiles3``, and the bounds it is laid over.

A tile coder covers a box of observation space with ``n_tilings`` uniform grids
(tilings) of ``tiles_per_dim`` tiles per dimension. Each tiling is displaced from
the first by a fraction of a tile: tiling ``t`` moves by ``t * (2d + 1) / n_tilings``
tile widths along dimension ``d``, i.e. by the displacement vector ``(1, 3, 5, ...)``
in units of ``1 / n_tilings`` of a tile (Sutton & Barto 2018, §9.5.4; Sutton's
``tiles3``). An observation activates exactly one tile in every tiling.

A tile is named by integer coordinates ``(t, c_0, ..., c_{n-1})`` and turned into an
index in ``[0, size)`` by an index hash table (IHT): tiles get indices in the order
in which they are first met, so the indices in use are always ``0 .. n_used - 1``.
When all ``size`` indices are taken, an unseen tile falls back to a hash of its
coordinates (``tiles3``'s ``overfullCount`` is :attr:`TileCoder.overflows` here).

Differences from ``tiles3``, all deliberate:

- Observations are given in their own units with ``bounds``; the coder scales them
  so that one tile is ``(high - low) / tiles_per_dim`` wide and tiling 0 starts at
  ``low``. (``tiles3`` expects pre-scaled floats and starts its grid at 0.)
- The fallback hash is a fixed 64-bit mix of the coordinates rather than Python's
  built-in ``hash``, whose value for tuples differs between Python versions, so a
  saved agent means the same thing everywhere.
- ``readonly`` queries of an unseen tile return ``-1`` while the table has room
  (``tiles3`` returns None) and the hash once it is full (the index learning would
  use), without counting an overflow.

Observations outside the bounds are not clipped (neither are they in ``tiles3``):
they fall in tiles beyond the edge, which get indices like any other.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from avq._validate import check_int

__all__ = ["TileCoder", "tile_hash"]

_MASK64 = (1 << 64) - 1


def tile_hash(coords: tuple[int, ...]) -> int:
    """A fixed 64-bit hash of a tile's integer coordinates (FNV-1a over the integers, then
    the MurmurHash3 finalizer so that the low bits used by ``% size`` are well mixed)."""
    h = 0xCBF29CE484222325
    for c in coords:
        h = ((h ^ (c & _MASK64)) * 0x100000001B3) & _MASK64
    h ^= h >> 33
    h = (h * 0xFF51AFD7ED558CCD) & _MASK64
    h ^= h >> 33
    h = (h * 0xC4CEB9FE1A85EC53) & _MASK64
    h ^= h >> 33
    return h


class TileCoder:
    """Sutton's ``tiles3`` tile coder with an index hash table, for observations in a box.

    Args:
        bounds: ``(low, high)`` per dimension, finite with ``low < high``.
        tiles_per_dim: Tiles per dimension in one tiling (across ``high - low``); an
            int or one per dimension. Each tiling has one more tile per dimension than
            this, to cover the part the displacement pushes past ``high``.
        n_tilings: Number of tilings. ``tiles3`` recommends a power of two at least
            ``4 * n_dims`` so that the displacements ``(1, 3, 5, ...)`` stay distinct.
        size: Number of indices (the size of the weight table the indices address).

    Attributes:
        n_used: Indices handed out so far (``0 .. n_used - 1``), at most ``size``.
        overflows: Number of times an unseen tile had to be hashed because the table
            was full (``tiles3``'s ``overfullCount``).

    Example:
        >>> coder = TileCoder([(0.0, 1.0)], tiles_per_dim=2, n_tilings=2, size=64)
        >>> coder(np.array([0.1])).tolist(), coder(np.array([0.6])).tolist()
        ([0, 1], [2, 3])
    """

    def __init__(
        self,
        bounds: Sequence[tuple[float, float]],
        tiles_per_dim: int | Sequence[int] = 8,
        n_tilings: int = 8,
        size: int = 4096,
    ) -> None:
        b = np.asarray(bounds, dtype=np.float64)
        if b.ndim != 2 or b.shape[1] != 2 or b.shape[0] < 1:
            raise ValueError(f"bounds must be a sequence of (low, high) pairs, not {bounds!r}")
        if not (np.all(np.isfinite(b)) and np.all(b[:, 1] > b[:, 0])):
            raise ValueError(f"bounds must be finite with low < high in every dimension, not {b.tolist()}")
        self.n_dims = b.shape[0]
        self.low = b[:, 0].copy()
        self.high = b[:, 1].copy()
        tpd = np.broadcast_to(np.asarray(tiles_per_dim), (self.n_dims,))
        if not np.issubdtype(tpd.dtype, np.integer) or np.any(tpd < 1):
            raise ValueError(f"tiles_per_dim must be an integer >= 1 or one per dimension, not {tiles_per_dim!r}")
        self.tiles_per_dim = tpd.astype(np.int64)
        self.n_tilings = check_int("n_tilings", n_tilings, 1)
        self.size = check_int("size", size, 1)
        # Observation -> tile units (one tile = 1) -> units of 1/n_tilings of a tile.
        self._to_units = self.tiles_per_dim / (self.high - self.low) * self.n_tilings
        # tiles3: tiling t is displaced by t * (2d + 1) / n_tilings tiles along dimension d.
        t = np.arange(self.n_tilings, dtype=np.int64)[:, None]
        offsets = t * (2 * np.arange(self.n_dims, dtype=np.int64)[None, :] + 1)  # (n_tilings, n_dims)
        self._offsets_by_dim = offsets.T.tolist()
        self._tiling_ids = range(self.n_tilings)
        self._low_list = self.low.tolist()
        self._to_units_list = self._to_units.tolist()
        self._index: dict[tuple[int, ...], int] = {}
        self.n_used = 0
        self.overflows = 0

    def __repr__(self) -> str:
        bounds = list(zip(self.low.tolist(), self.high.tolist()))
        return (
            f"TileCoder(bounds={bounds}, tiles_per_dim={self.tiles_per_dim.tolist()}, "
            f"n_tilings={self.n_tilings}, size={self.size})"
        )

    @property
    def full(self) -> bool:
        """Whether every index has been handed out (unseen tiles are hashed from now on)."""
        return self.n_used >= self.size

    def coordinates(self, x: np.ndarray) -> np.ndarray:
        """The active tile of every tiling as integer coordinates, ``(n_tilings, 1 + n_dims)``.

        Row ``t`` is ``(t, c_0, ..., c_{n-1})`` with ``c_d = (q_d + t * (2d + 1)) // n_tilings``
        and ``q_d = floor((x_d - low_d) * tiles_per_dim_d / (high_d - low_d) * n_tilings)``,
        exactly ``tiles3``'s coordinates of the scaled observation.
        """
        return np.array(self._keys(x), dtype=np.int64)

    def _keys(self, x: np.ndarray) -> list[tuple[int, ...]]:
        # Plain Python on a handful of numbers: several times faster than NumPy here.
        xs = np.asarray(x, dtype=np.float64).tolist()
        if not isinstance(xs, list) or len(xs) != self.n_dims:
            raise ValueError(f"x has shape {np.shape(x)}; the tile coder has {self.n_dims} dimensions")
        try:
            q = [math.floor((v - lo) * u) for v, lo, u in zip(xs, self._low_list, self._to_units_list)]
        except (OverflowError, ValueError):
            raise ValueError(f"x must be finite, not {xs}") from None
        n = self.n_tilings
        columns = [[(qd + o) // n for o in offs] for qd, offs in zip(q, self._offsets_by_dim)]
        return list(zip(self._tiling_ids, *columns))

    def __call__(self, x: np.ndarray, readonly: bool = False) -> np.ndarray:
        """Indices of the ``n_tilings`` tiles active at ``x`` (one per tiling, in tiling order).

        Args:
            x: One observation, ``(n_dims,)``.
            readonly: Do not hand out new indices or count overflows; an unseen tile is
                ``-1`` while the table has room, its hash once the table is full.

        Returns:
            ``(n_tilings,)`` int64 indices in ``[0, size)`` (or ``-1``, see ``readonly``).
            Two tilings can share an index only after the table has overflowed.
        """
        index = self._index
        keys = self._keys(x)
        out = [index.get(key) for key in keys]
        if None in out:
            out = [self._unseen(key, readonly) if i is None else i for key, i in zip(keys, out)]
        return np.array(out, dtype=np.int64)

    def _unseen(self, key: tuple[int, ...], readonly: bool) -> int:
        if self.n_used >= self.size:
            if not readonly:
                self.overflows += 1
            return tile_hash(key) % self.size
        if readonly:
            return -1
        i = self.n_used
        self._index[key] = i
        self.n_used += 1
        return i

    # -- saving -------------------------------------------------------------------------
    def tiles(self) -> np.ndarray:
        """The coordinates of the tiles in use, row ``i`` = the tile with index ``i``,
        ``(n_used, 1 + n_dims)`` int64 (what :meth:`restore` needs)."""
        out = np.array(list(self._index), dtype=np.int64).reshape(-1, self.n_dims + 1)
        return out

    def restore(self, tiles: np.ndarray, overflows: int = 0) -> None:
        """Refill an empty coder with the tiles of :meth:`tiles`, in index order.

        Raises:
            ValueError: the coder is not empty, or ``tiles`` has the wrong shape, too
                many rows or repeated rows.
        """
        tiles = np.asarray(tiles)
        if self.n_used:
            raise ValueError("restore needs an empty tile coder")
        if tiles.ndim != 2 or tiles.shape[1] != self.n_dims + 1 or len(tiles) > self.size:
            raise ValueError(
                f"tiles of shape {tiles.shape} do not fit a coder of {self.n_dims} dims and size {self.size}"
            )
        for row in tiles.tolist():
            key = tuple(int(c) for c in row)
            if key in self._index:
                raise ValueError(f"tile {key} appears twice")
            self._index[key] = self.n_used
            self.n_used += 1
        self.overflows = int(overflows)
