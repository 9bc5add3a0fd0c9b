"""The per-episode records of an agent, stored as columns."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any, overload

import numpy as np

#: The fields of one record, in column order. ``return`` and ``wall_s`` are floats, the rest integers.
HISTORY_FIELDS = ("episode", "steps", "return", "n_cells", "appends", "merges", "refused", "decisions", "wall_s")
_FLOAT_FIELDS = frozenset({"return", "wall_s"})
_RETURN = HISTORY_FIELDS.index("return")


class EpisodeHistory(Sequence[dict[str, Any]]):
    """One row per finished episode, kept in a growing ``float64`` array.

    Indexing gives a row as a dict of plain Python numbers (like the records a
    ``callback`` receives); :meth:`columns` gives every field as an array. The fused
    training loops add thousands of episodes per call without building a dict for
    each. Integers are exact up to 2**53.
    """

    def __init__(self) -> None:
        self._data = np.zeros((0, len(HISTORY_FIELDS)))
        self._n = 0
        #: The lowest return of the first ``_lowest_of`` records (:meth:`lowest_return` reads only the rows since).
        self._lowest, self._lowest_of = np.inf, 0

    def __len__(self) -> int:
        return self._n

    @overload
    def __getitem__(self, index: int) -> dict[str, Any]: ...

    @overload
    def __getitem__(self, index: slice) -> list[dict[str, Any]]: ...

    def __getitem__(self, index: int | slice) -> dict[str, Any] | list[dict[str, Any]]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._n))]
        i = int(index)
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError(f"episode index {index} out of range for {self._n} episodes")
        row = self._data[i]
        return {f: (float(v) if f in _FLOAT_FIELDS else int(v)) for f, v in zip(HISTORY_FIELDS, row)}

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return (self[i] for i in range(self._n))

    def __repr__(self) -> str:
        return f"EpisodeHistory({self._n} episodes)"

    def _reserve(self, k: int) -> np.ndarray:
        need = self._n + k
        if need > self._data.shape[0]:
            grown = np.zeros((max(need, 2 * self._data.shape[0], 64), len(HISTORY_FIELDS)))
            grown[: self._n] = self._data[: self._n]
            self._data = grown
        block = self._data[self._n : need]
        self._n = need
        return block

    def append(self, record: dict[str, Any]) -> None:
        """Add one record (a dict with every field of :data:`HISTORY_FIELDS`)."""
        self._reserve(1)[0] = [record[f] for f in HISTORY_FIELDS]

    def extend_block(self, first_episode: int, rows: np.ndarray, wall_s: np.ndarray) -> None:
        """Add ``rows`` (one per episode: the fields after ``episode``, before ``wall_s``)."""
        block = self._reserve(len(rows))
        block[:, 0] = np.arange(first_episode, first_episode + len(rows))
        block[:, 1:-1] = rows
        block[:, -1] = wall_s

    def as_array(self) -> np.ndarray:
        """A copy of the records, one row per episode, columns in :data:`HISTORY_FIELDS` order."""
        return self._data[: self._n].copy()

    @classmethod
    def from_array(cls, data: np.ndarray) -> EpisodeHistory:
        """The history held in ``data`` (as returned by :meth:`as_array`), checked."""
        data = np.asarray(data)
        if data.ndim != 2 or data.shape[1] != len(HISTORY_FIELDS) or not np.issubdtype(data.dtype, np.floating):
            raise ValueError(
                f"array history has shape {data.shape} and dtype {data.dtype}; "
                f"expected (episodes, {len(HISTORY_FIELDS)}) floats"
            )
        history = cls()
        history._reserve(len(data))[:] = data
        return history

    def lowest_return(self) -> float | None:
        """The lowest ``return`` of the episodes recorded; None when no episode finished. (Read at every greedy
        ``predict`` of a planning agent: only the records added since the last call are scanned.)"""
        if self._n == 0:
            return None
        if self._lowest_of < self._n:
            self._lowest = min(self._lowest, float(self._data[self._lowest_of : self._n, _RETURN].min()))
            self._lowest_of = self._n
        return self._lowest

    def columns(self) -> dict[str, np.ndarray]:
        """Every field as an array (``int64`` or ``float64``); empty when no episode finished."""
        if self._n == 0:
            return {}
        data = self._data[: self._n]
        return {
            f: (data[:, k].copy() if f in _FLOAT_FIELDS else data[:, k].astype(np.int64))
            for k, f in enumerate(HISTORY_FIELDS)
        }
