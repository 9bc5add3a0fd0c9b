"""A ``numpy.random.Generator``'s own draws for compiled code that is called once per step.

Handing a ``Generator`` to a Numba function costs about 10 µs a call (its bit generator is
unboxed through ``ctypes`` every time), far more than a step of the agents' work. The
generic training paths therefore draw through a :class:`RawStream`: a buffer of raw 64-bit
outputs of the agent's PCG64 bit generator (``bit_generator.random_raw``), from which the
compiled draws below compute exactly what the generator itself would have returned:

* ``random()`` is ``(raw >> 11) * 2**-53`` (NumPy's ``next_double``);
* ``integers(0, n)`` is Lemire's bounded draw on a 32-bit output, as NumPy's
  ``random_bounded_uint64`` does for ranges below 2**32, where a 32-bit output is one
  half of a raw output and the other half is kept for the next one (PCG64's
  ``has_uint32`` / ``uinteger``); ``n == 1`` draws nothing.

:meth:`RawStream.sync` then puts the generator where those draws would have left it
(the state before the buffer was filled, advanced by the raw outputs used, with the kept
half), so that the generator and the compiled draws are one stream: code that draws from
the generator directly (the fused loops, through Numba's ``Generator`` support) continues
exactly where the compiled draws stopped, and the other way round.

A source of draws is either a ``Generator`` (inside a fused loop) or the tuple
``(raw, cursor)`` of a :class:`RawStream`; :func:`uniform` and :func:`below` take both.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, cast

import numpy as np
from numba import njit, types
from numba.extending import overload
from numba.np.random.generator_core import next_uint32
from numba.np.random.random_methods import buffered_bounded_lemire_uint32

__all__ = ["RawStream", "uniform", "below", "DRAWS_PER_DECISION"]

#: Raw outputs one ε-greedy decision needs at most (three), with room to spare for Lemire rejections
#: (each has probability below m / 2**32): what :meth:`RawStream.reserve` makes sure of by default.
DRAWS_PER_DECISION = 16
#: ``cursor`` fields: next unused raw output, whether half of an output is kept, that half.
POS, HAS32, HALF = 0, 1, 2
_MASK32 = np.uint64(0xFFFFFFFF)


@njit(cache=True, inline="always")
def _next64(raw, cursor) -> np.uint64:
    k = cursor[POS]
    if k >= raw.shape[0]:
        raise RuntimeError("avq: the buffer of random draws ran out (ask for more room before a step)")
    cursor[POS] = k + 1
    return raw[k]


@njit(cache=True, inline="always")
def _next32(raw, cursor) -> np.uint64:
    if cursor[HAS32]:
        cursor[HAS32] = 0
        return np.uint64(cursor[HALF])
    v = _next64(raw, cursor)
    cursor[HAS32] = 1
    cursor[HALF] = np.int64(v >> np.uint64(32))
    return v & _MASK32


# (raw_uniform and raw_below are not inlined at Numba's IR level: inlining raw_below's loop through the
# overloads below trips a pedantic check of Numba's that warns at compile time; LLVM inlines them anyway.)
@njit(cache=True)
def raw_uniform(raw, cursor) -> float:
    """``Generator.random()``."""
    return float(_next64(raw, cursor) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def raw_below(raw, cursor, n: int) -> int:
    """``Generator.integers(0, n)`` for ``1 <= n <= 2**32``."""
    if n == 1:
        return 0
    excl = np.uint64(n)
    m = _next32(raw, cursor) * excl
    left = m & _MASK32
    if left < excl:
        threshold = (_MASK32 - (excl - np.uint64(1))) % excl
        while left < threshold:
            m = _next32(raw, cursor) * excl
            left = m & _MASK32
    return np.int64(m >> np.uint64(32))


def uniform(src):  # pragma: no cover - replaced by the overload in compiled code
    """A uniform draw in [0, 1) from ``src`` (a ``Generator`` or a ``(raw, cursor)`` stream)."""
    raise NotImplementedError


def below(src, n):  # pragma: no cover - replaced by the overload in compiled code
    """A uniform integer in [0, n) from ``src``, as ``Generator.integers(0, n)``."""
    raise NotImplementedError


# Inlined at Numba's IR level (inline="always"): a Generator handed to a function that is not inlined
# is reference-counted at every call, which costs a third of a decision (benchmarks/speed.py, 2b).
@overload(uniform, inline="always")
def _uniform(src):
    if isinstance(src, types.NumPyRandomGeneratorType):

        def from_generator(src):
            return src.random()

        return from_generator
    if isinstance(src, types.BaseTuple):

        def from_stream(src):
            return raw_uniform(src[0], src[1])

        return from_stream
    return None


@overload(below, inline="always")
def _below(src, n):
    if isinstance(src, types.NumPyRandomGeneratorType):

        def from_generator(src, n):
            # What Numba's src.integers(0, n) draws (NumPy's bounded Lemire on 32-bit outputs), without the
            # one-element array it allocates at every call; outside 1 <= n <= 2**32, Numba's own.
            r = np.int64(n) - np.int64(1)
            if r == 0:
                return np.int64(0)
            if r < 0 or r > 0xFFFFFFFF:
                return src.integers(0, n)
            if r == 0xFFFFFFFF:
                return np.int64(next_uint32(src.bit_generator))
            return np.int64(buffered_bounded_lemire_uint32(src.bit_generator, r))

        return from_generator
    if isinstance(src, types.BaseTuple):

        def from_stream(src, n):
            return raw_below(src[0], src[1], n)

        return from_stream
    return None


class RawStream:
    """Raw outputs of ``rng``'s PCG64 bit generator, consumed by compiled draws.

    Call :meth:`reserve` before compiled code draws (it makes sure ``need`` raw outputs
    are left), hand :attr:`src` to that code, and :meth:`sync` before anything else uses
    ``rng`` (saving it, a fused loop, another library). Between :meth:`reserve` and
    :meth:`sync` the generator itself is ahead of the stream and must not be used.
    """

    def __init__(self, rng: np.random.Generator, size: int = 4096) -> None:
        if type(rng.bit_generator).__name__ != "PCG64":
            raise TypeError(f"RawStream needs a PCG64 generator, not {type(rng.bit_generator).__name__}")
        self.rng = rng
        self.size = int(size)
        self.raw = np.zeros(0, dtype=np.uint64)
        self.cursor = np.zeros(3, dtype=np.int64)
        self._start: Mapping[str, Any] | None = None  # the generator's state when the buffer was filled

    @property
    def src(self) -> tuple[np.ndarray, np.ndarray]:
        """The source of draws for :func:`uniform` and :func:`below`."""
        return self.raw, self.cursor

    def reserve(self, need: int = DRAWS_PER_DECISION) -> None:
        """Make sure at least ``need`` raw outputs are left in the buffer."""
        if self._start is not None and self.raw.shape[0] - self.cursor[POS] >= need:
            return
        self.sync()
        bg = self.rng.bit_generator
        state = bg.state
        self._start = state
        self.cursor[:] = (0, state["has_uint32"], state["uinteger"])
        self.raw = bg.random_raw(max(self.size, need))

    def sync(self) -> None:
        """Leave the generator exactly where the draws taken so far would have left it."""
        if self._start is None:
            return
        bg = self.rng.bit_generator
        bg.state = self._start
        cast(np.random.PCG64, bg).advance(int(self.cursor[POS]))  # (advance clears the kept half: set it after)
        state = dict(bg.state)  # (a new dict each time, typed as a read-only Mapping)
        state["has_uint32"], state["uinteger"] = int(self.cursor[HAS32]), int(self.cursor[HALF])
        bg.state = state
        self._start = None
        self.raw = self.raw[:0]
        self.cursor[:] = 0
