"""The planner's queue: a max-heap of states by priority, on the model's arrays ``heap``, ``hpos`` (a state's
place in the heap, or -1) and ``prio``, its length in ``C[HEAP_N]`` (:mod:`avq.agents.plan.model`).

Its functions take those arrays themselves, not the model's record: they are small, inlined everywhere,
and a reader sees what they touch."""

from __future__ import annotations

from numba import njit

__all__ = ["HEAP_N", "push", "pop"]

#: The queue's length, in the model's counters ``C``.
HEAP_N = 3


@njit(cache=True, inline="always")
def _swap(heap, hpos, i: int, j: int) -> None:
    si, sj = heap[i], heap[j]
    heap[i], heap[j] = sj, si
    hpos[sj], hpos[si] = i, j


@njit(cache=True, inline="always")
def _sift_up(heap, hpos, prio, i: int) -> None:
    while i > 0:
        parent = (i - 1) // 2
        if prio[heap[parent]] >= prio[heap[i]]:
            return
        _swap(heap, hpos, i, parent)
        i = parent


@njit(cache=True, inline="always")
def push(heap, hpos, prio, C, s: int, p: float) -> None:
    """Queue ``s`` with priority ``p``, or raise its priority to ``p`` (the queue's arrays of the model)."""
    i = hpos[s]
    if i < 0:
        i = C[HEAP_N]
        heap[i] = s
        hpos[s] = i
        prio[s] = p
        C[HEAP_N] = i + 1
    elif p > prio[s]:
        prio[s] = p
    else:
        return
    _sift_up(heap, hpos, prio, i)


@njit(cache=True, inline="always")
def pop(heap, hpos, prio, C) -> int:
    """The queued state of highest priority, taken off the queue."""
    top = heap[0]
    n = C[HEAP_N] - 1
    C[HEAP_N] = n
    hpos[top] = -1
    if n > 0:
        last = heap[n]
        heap[0] = last
        hpos[last] = 0
        i = 0
        while True:
            left = 2 * i + 1
            if left >= n:
                break
            best = left
            if left + 1 < n and prio[heap[left + 1]] > prio[heap[left]]:
                best = left + 1
            if prio[heap[best]] <= prio[heap[i]]:
                break
            _swap(heap, hpos, i, best)
            i = best
    return top
