"""``avq-plan``'s remembered transitions, and how the model follows them when the cells change.

The last ``memory`` aggregate transitions are kept with their start and end observations
(:func:`remember`). When the codebook changes, each remembered transition whose start or end
observation now lies in another cell is moved in the model (removed from its old pair and added to
the new one: :func:`relocate`), so that the model describes the current partition by what was seen.
Beyond ``memory``, the oldest transition is overwritten: it stays in the model where it was.

A transition that ended only because the cell changed (a *crossing*: no collision, no end of the episode) and
whose two ends come to lie in one cell (cells merged; with ``compose_crossings`` also a cell cut, or the metric
changed) is recorded as going on (:data:`~avq.agents.plan.model.CONT`): :func:`successor`. Otherwise it stays in
the model as a decision that ended in its own cell, one that costs its return and is then taken again.
A crossing is kept as :data:`COMPOSED` (it goes on) or :data:`HELD` (``compose_crossings="noise"``: it is
remembered as a crossing, but goes on only once :func:`relocate` is told to compose the held ones, when the noise
test leaves dimensions out of the metric).
"""

from __future__ import annotations

from numba import njit

from avq.agents.plan.model import CONT, FIRST, ModelArrays, record
from avq.agents.plan.queue import push
from avq.agents.plan.state import MEM_N, MEM_POS, SIZE, PlanArrays, PlanIntParam
from avq.quantizer import nearest_index

__all__ = ["remember", "relocate", "record_with_start", "successor", "COMPOSED", "HELD"]

#: A remembered transition's crossing flag: a crossing that goes on where its two ends lie in one cell.
COMPOSED = 1
#: A crossing that does not go on (yet): ``relocate(..., compose_held=True)`` makes it :data:`COMPOSED`.
HELD = 2


@njit(cache=True, inline="always")
def successor(start: int, end: int, crossing: int) -> int:
    """The successor in the model of a transition from cell ``start`` to cell ``end`` (-1: terminal):
    :data:`~avq.agents.plan.model.CONT` for a :data:`COMPOSED` crossing that ends in the cell it started in (the
    decision goes on)."""
    return CONT if crossing == COMPOSED and end == start else end


@njit(cache=True, inline="always")
def _row_distance2(X, t: int, off: int, V, i: int, inv_scale) -> float:
    """Squared scaled distance from the stored observation ``X[t, off:off + n]`` to vector ``i`` (the
    arithmetic of :func:`avq.quantizer.nearest_index`)."""
    s = 0.0
    for d in range(V.shape[1]):
        z = (V[i, d] - X[t, off + d]) * inv_scale[d]
        s += z * z
    return s


@njit(cache=True, inline="always")
def _cell_after(V, size: int, X, t: int, off: int, k: int, u: int, w: int, inv_scale) -> int:
    """The cell of the stored observation ``X[t, off:]``, which was in cell ``k``, after vectors ``u`` and
    ``w`` changed (moved or new): among ``k``, ``u``, ``w`` unless it was in one of them or ``u < 0`` (the
    metric changed: then among all), lowest index on ties as :func:`avq.quantizer.nearest_index`."""
    if k == u or k == w or u < 0:
        best, _ = nearest_index(V, size, X[t, off : off + V.shape[1]], inv_scale)
        return best
    best = k
    best_d = _row_distance2(X, t, off, V, k, inv_scale)
    d = _row_distance2(X, t, off, V, u, inv_scale)
    if d < best_d or (d == best_d and u < best):
        best, best_d = u, d
    if w != u:  # (written out, not a loop over (u, w): this runs for every remembered transition)
        d = _row_distance2(X, t, off, V, w, inv_scale)
        if d < best_d or (d == best_d and w < best):
            best = w
    return best


@njit(cache=True, inline="always")
def cell_after_merge(V, size: int, X, t: int, off: int, k: int, mapping, half, merged, inv_scale) -> int:
    """The cell of the stored observation ``X[t, off:]``, which was in cell ``k``, after a merge pass
    (:func:`avq.quantizer.merge_kernel`'s ``mapping``; ``half[k]``: ``k`` was one of a merged pair; ``merged``:
    the merged cells' new indices): among all cells if it was in a merged pair, else among its own cell (now
    ``mapping[k]``) and the merged cells, whose vectors alone moved; lowest index on ties as
    :func:`avq.quantizer.nearest_index`."""
    if half[k]:
        best, _ = nearest_index(V, size, X[t, off : off + V.shape[1]], inv_scale)
        return best
    best = mapping[k]
    best_d = _row_distance2(X, t, off, V, best, inv_scale)
    for q in range(merged.shape[0]):
        c = merged[q]
        d = _row_distance2(X, t, off, V, c, inv_scale)
        if d < best_d or (d == best_d and c < best):
            best, best_d = c, d
    return best


@njit(cache=True, inline="always")
def record_with_start(
    m: ModelArrays, e_xs, X, t: int, s: int, a: int, r: float, disc: float, s2: int, sign: int
) -> None:
    """:func:`avq.agents.plan.model.record`, and the transition's start ``X[t, :n]`` added to (or removed from)
    its edge's sum of starts ``e_xs``."""
    e = record(m, s, a, r, disc, s2, sign)
    for d in range(e_xs.shape[1]):
        e_xs[e, d] += sign * X[t, d]
    if m.e_n[e] == 0:
        for d in range(e_xs.shape[1]):
            e_xs[e, d] = 0.0


@njit(cache=True)
def relocate(ag: PlanArrays, m: ModelArrays, u: int, w: int, compose_held: bool = False) -> None:
    """After vectors ``u`` and ``w`` changed (``u = w = -1``: the metric changed), move every remembered
    transition whose start or end cell changed to its new pair in the model (and queue both cells' backups).
    ``compose_held``: every :data:`HELD` crossing becomes :data:`COMPOSED` (and moves in the model where that
    changes its successor)."""
    V, inv_scale, mem_x, mem_i, mem_f = ag.V, ag.inv_scale, ag.mem_x, ag.mem_i, ag.mem_f
    e_xs, heap, hpos, prio, C = ag.e_xs, m.heap, m.hpos, m.prio, m.C  # (written: see the note on ModelArrays)
    n = V.shape[1]
    size = ag.S[SIZE]
    for t in range(ag.S[MEM_N]):
        a, cs, ce, cross = mem_i[t, 0], mem_i[t, 1], mem_i[t, 2], mem_i[t, 3]
        now = COMPOSED if compose_held and cross == HELD else cross
        ns = _cell_after(V, size, mem_x, t, 0, cs, u, w, inv_scale)
        ne = ce if ce < 0 else _cell_after(V, size, mem_x, t, n, ce, u, w, inv_scale)
        mem_i[t, 3] = now
        if ns == cs and ne == ce and successor(cs, ce, cross) == successor(ns, ne, now):
            continue
        record_with_start(m, e_xs, mem_x, t, cs, a, mem_f[t, 0], mem_f[t, 1], successor(cs, ce, cross), -1)
        record_with_start(m, e_xs, mem_x, t, ns, a, mem_f[t, 0], mem_f[t, 1], successor(ns, ne, now), 1)
        push(heap, hpos, prio, C, cs, FIRST)
        push(heap, hpos, prio, C, ns, FIRST)
        mem_i[t, 1] = ns
        mem_i[t, 2] = ne
    if u >= 0:
        push(heap, hpos, prio, C, u, FIRST)
        push(heap, hpos, prio, C, w, FIRST)


@njit(cache=True, inline="always")
def start_after_growth(ag: PlanArrays, t: int, i: int, grown_from: int) -> int:
    """The cell that the start of remembered transition ``t``, taken as a decision of cell ``i``, lies in now that
    the cells from ``grown_from`` on (at most two) were appended during the transition's last step: ``i`` or one
    of them (:func:`_cell_after`)."""
    size = ag.S[SIZE]
    return _cell_after(ag.V, size, ag.mem_x, t, 0, i, grown_from, size - 1, ag.inv_scale)


@njit(cache=True, inline="always")
def remember(ag: PlanArrays, x, a: int, i: int, j: int, R: float, disc: float, crossing: int) -> None:
    """Keep the transition ``(i, a) -> j`` from ``ag.xs`` to ``x`` (``crossing``: 0, or :data:`COMPOSED` or
    :data:`HELD` when it ended only because the cell changed) in the memory. When it is full, the oldest
    is overwritten: it stays in the model, in the cells it was in, but no longer follows their changes."""
    S, IP, xs, mem_x, mem_i, mem_f = ag.S, ag.IP, ag.xs, ag.mem_x, ag.mem_i, ag.mem_f
    t = S[MEM_POS]
    if S[MEM_N] < IP[PlanIntParam.MEMORY]:
        S[MEM_N] += 1
    n = x.shape[0]
    for d in range(n):
        mem_x[t, d] = xs[d]
        mem_x[t, n + d] = x[d]
    mem_i[t, 0] = a
    mem_i[t, 1] = i
    mem_i[t, 2] = j
    mem_i[t, 3] = crossing
    mem_f[t, 0] = R
    mem_f[t, 1] = disc
    S[MEM_POS] = (t + 1) % IP[PlanIntParam.MEMORY]
