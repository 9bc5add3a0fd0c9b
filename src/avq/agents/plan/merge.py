"""``avq-plan``'s merging: the paper's second mechanism (docs: explanation/paper.md, Merging) under a learned
model, with the merged cell's model *composed* from its halves' transitions rather than averaged.

At the end of an episode (``rho`` set, and the memory still holding every transition seen):

1. each cell whose every decision is known looks, among its ``merge_neighbours`` nearest cells whose every
   decision is known too (and, with ``merge_same_action``, whose greedy action is the same), for the one whose
   action-value profile is closest (the paper's mean square difference,
   :func:`avq.rules.mean_square_difference`); a pair under ``rho`` is a candidate;
2. candidates are merged most similar first, each cell in one merge at most, unless the greedy decision of
   either half would not leave the merged cell in what was seen (:func:`avq.rules.merged_decision_leaves`:
   the paper gives a decision that cannot leave its cell the value ``chi``; here such a merge is refused);
3. the first cell's vector moves to the midpoint and the second is removed, the cells after it moving down
   (:func:`avq.quantizer.merge_kernel`), their values with them;
4. the model is rebuilt from the memory (:func:`rebuild`): every remembered transition is recorded again
   between the cells its start and end observations now lie in, and a transition that ended only because
   the cell changed, whose two ends now lie in one cell, as a decision that goes on
   (:data:`avq.agents.plan.model.CONT`). So a merged cell's decision is valued as it would be run (it goes on
   across the old border) without being explored again, and a later split cuts it by what was seen.

The planned values are kept as a start: every cell is queued and the values converge over the next steps.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from avq.agents.plan import model as _model
from avq.agents.plan.memory import cell_after_merge, record_with_start, successor
from avq.agents.plan.model import ModelArrays, settled
from avq.agents.plan.state import GEOM, MEM_N, SIZE, SLOPE_N, SLOPE_SUM, PlanArrays, PlanIntParam, PlanParam
from avq.quantizer import compact_rows, disjoint_pairs, merge_kernel
from avq.rules import mean_square_difference, merged_decision_leaves, outcome_disagrees, same_greedy_action

__all__ = [
    "MODEL_MERGE_PARAMS",
    "merge_pass",
    "rebuild",
    "nearest_cells",
    "exits_after_merge",
    "outcomes_agree",
    "value_slope",
]

#: The options of merging under a model that an agent without one does not have (``rho`` is ``AVQSarsa``'s too).
MODEL_MERGE_PARAMS = ("merge_neighbours",)


@njit(cache=True)
def nearest_cells(V, size: int, i: int, k: int, inv_scale, out) -> int:
    """The (at most) ``k`` cells nearest to cell ``i``'s vector, nearest first (lowest index on ties), into
    ``out``; returns how many."""
    dist = np.full(k, np.inf)
    found = 0
    for j in range(size):
        if j == i:
            continue
        s = 0.0
        for d in range(V.shape[1]):
            z = (V[i, d] - V[j, d]) * inv_scale[d]
            s += z * z
        if found < k:
            found += 1
        elif not s < dist[k - 1]:
            continue
        p = found - 1
        while p > 0 and s < dist[p - 1]:
            dist[p] = dist[p - 1]
            out[p] = out[p - 1]
            p -= 1
        dist[p] = s
        out[p] = j
    return found


@njit(cache=True, inline="always")
def value_slope(P, F) -> float:
    """``L``: ``value_slope`` if given, else the mean return per unit of scaled distance travelled by the
    transitions without a collision so far (0 before the first)."""
    if P[PlanParam.VALUE_SLOPE] >= 0.0:
        return P[PlanParam.VALUE_SLOPE]
    return F[SLOPE_SUM] / F[SLOPE_N] if F[SLOPE_N] > 0 else 0.0


@njit(cache=True)
def outcomes_agree(ag: PlanArrays, m: ModelArrays, i: int, j: int, a: int) -> bool:
    """Whether the outcome split (:mod:`avq.agents.plan.kernels`) would leave the merged cell of ``i`` and ``j``
    whole for decision ``a``: no two of the successors of ``(i, a)`` and ``(j, a)`` have mean outcomes that differ
    by more than ``split_threshold`` beyond what the distance between their mean starts explains (a successor in
    ``i`` or ``j``, or going on, is worth ``Q``: the decision would go on). A merge that the split would undo
    at once is refused."""
    e_xs, inv_scale, n = ag.e_xs, ag.inv_scale, ag.e_xs.shape[1]
    slope, threshold = value_slope(ag.P, ag.F), ag.P[PlanParam.SPLIT_THRESHOLD]
    for c1 in (i, j):
        e1 = m.head[c1, a]
        while e1 >= 0:
            k1 = m.e_n[e1]
            if k1 > 0:
                v1 = _outcome(m, e1, i, j, c1, a)
                for c2 in (i, j):
                    e2 = m.head[c2, a]
                    while e2 >= 0:
                        k2 = m.e_n[e2]
                        if k2 > 0 and e2 != e1:
                            dist = 0.0
                            for d in range(n):
                                z = (e_xs[e1, d] / k1 - e_xs[e2, d] / k2) * inv_scale[d]
                                dist += z * z
                            gap = abs(v1 - _outcome(m, e2, i, j, c2, a)) - slope * np.sqrt(dist)
                            if outcome_disagrees(gap, threshold):
                                return False
                        e2 = m.e_next[e2]
            e1 = m.e_next[e1]
    return True


@njit(cache=True, inline="always")
def _outcome(m: ModelArrays, e: int, i: int, j: int, c: int, a: int) -> float:
    """The mean outcome of edge ``e`` of ``(c, a)``, as it would be in the merged cell of ``i`` and ``j``."""
    t = m.e_to[e]
    later = 0.0 if t == -1 else (m.Q[c, a] if t in (i, j) or t < 0 else m.V[t])
    return (m.e_r[e] + m.e_disc[e] * later) / m.e_n[e]


@njit(cache=True)
def exits_after_merge(m: ModelArrays, i: int, j: int, a: int) -> int:
    """The transitions of decision ``a`` in cells ``i`` and ``j`` that would leave the cell they make: those that
    left either, less those from one into the other."""
    total = 0
    for c, other in ((i, j), (j, i)):
        total += m.cnt[c, a] - m.cint[c, a]
        e = m.head[c, a]
        while e >= 0:
            if m.e_to[e] == other:
                total -= m.e_n[e]
            e = m.e_next[e]
    return total


@njit(cache=True)
def rebuild(ag: PlanArrays, m: ModelArrays, pairs, mapping) -> None:
    """The model from the memory alone, in the cells after the merges ``pairs`` (old indices) that
    :func:`avq.quantizer.merge_kernel` mapped by ``mapping``: :func:`avq.agents.plan.model.clear`, then every
    remembered transition recorded again between the cells its start and end observations now lie in
    (:func:`avq.agents.plan.memory.cell_after_merge`: the memory's cells are those of the codebook before)."""
    V, inv_scale, mem_x, mem_i, mem_f, e_xs = ag.V, ag.inv_scale, ag.mem_x, ag.mem_i, ag.mem_f, ag.e_xs
    e_xs[: m.C[_model.N_EDGES]] = 0.0
    _model.clear(m)
    n, size = V.shape[1], ag.S[SIZE]
    half = np.zeros(mapping.shape[0], dtype=np.bool_)
    merged = np.empty(pairs.shape[0], dtype=np.int64)
    for q in range(pairs.shape[0]):
        half[pairs[q, 0]] = True
        half[pairs[q, 1]] = True
        merged[q] = mapping[pairs[q, 0]]
    for t in range(ag.S[MEM_N]):
        cs = cell_after_merge(V, size, mem_x, t, 0, mem_i[t, 1], mapping, half, merged, inv_scale)
        ce = mem_i[t, 2]
        if ce >= 0:
            ce = cell_after_merge(V, size, mem_x, t, n, ce, mapping, half, merged, inv_scale)
        mem_i[t, 1] = cs
        mem_i[t, 2] = ce
        target = successor(cs, ce, mem_i[t, 3])
        record_with_start(m, e_xs, mem_x, t, cs, mem_i[t, 0], mem_f[t, 0], mem_f[t, 1], target, 1)


@njit(cache=True, inline="always")
def _may_merge(ag: PlanArrays, m: ModelArrays, i: int, j: int) -> bool:
    """The refusals of a candidate pair: each half's greedy decision must leave the merged cell
    (:func:`avq.rules.merged_decision_leaves`) and, with the outcome split on, keep its outcomes together
    (:func:`outcomes_agree`)."""
    known = m.C[_model.KNOWN]
    for c in (i, j):
        a = int(np.argmax(m.Q[c]))
        if not merged_decision_leaves(exits_after_merge(m, i, j, a), known):
            return False
    if ag.IP[PlanIntParam.OUTCOME_SPLIT]:
        for c in (i, j):
            if not outcomes_agree(ag, m, i, j, int(np.argmax(m.Q[c]))):
                return False
    return True


@njit(cache=True, inline="always")
def _partner(ag: PlanArrays, m: ModelArrays, i: int, found: int) -> tuple[int, float]:
    """Cell ``i``'s partner among its ``found`` nearest cells (``ag.near[1 + i]``) and their profiles' mean
    square difference, or ``(-1, inf)``: both settled, the same greedy action (``merge_same_action``), the
    closest profile under ``rho`` (the first of the nearest on ties)."""
    Q, near = m.Q, ag.near
    rho, same_action = ag.P[PlanParam.RHO], ag.IP[PlanIntParam.MERGE_SAME_ACTION]
    best, gap = -1, np.inf
    if settled(m, i):
        for p in range(found):
            j = near[1 + i, p]
            if settled(m, j) and (not same_action or same_greedy_action(Q[i], Q[j])):
                g = mean_square_difference(Q[i], Q[j])
                if g < rho and g < gap:
                    best, gap = j, g
    return best, gap


@njit(cache=True)
def merge_pass(ag: PlanArrays, m: ModelArrays) -> int:
    """Merge the cells that the rules above allow, rebuild the model and return how many merges were made
    (0, changing nothing, when merging is off or the memory no longer holds every transition). Each cell's
    nearest cells are found again only when the codebook changed (``ag.near``); a pass that finds no
    candidate allocates nothing."""
    P, IP, S, V, Q, Vm, near = ag.P, ag.IP, ag.S, ag.V, m.Q, m.V, ag.near
    size = S[SIZE]
    if P[PlanParam.RHO] < 0.0 or size < 2 or S[MEM_N] >= IP[PlanIntParam.MEMORY]:
        return 0
    k = IP[PlanIntParam.MERGE_NEIGHBOURS]
    if near[0, 0] != S[GEOM]:
        for i in range(size):
            nearest_cells(V, size, i, k, ag.inv_scale, near[1 + i])
        near[0, 0] = S[GEOM]
    found = min(k, size - 1)
    first, j, g = 0, -1, np.inf
    while first < size:
        j, g = _partner(ag, m, first, found)
        if j >= 0:
            break
        first += 1
    if first == size:
        return 0  # (most passes)
    partner = np.full(size, -1, dtype=np.int64)
    gap = np.full(size, np.inf)
    partner[first], gap[first] = j, g
    for i in range(first + 1, size):
        partner[i], gap[i] = _partner(ag, m, i, found)
    for i in range(size):  # (a refused partner is no partner: the refusals depend on the pair alone)
        j = partner[i]
        if j >= 0 and not _may_merge(ag, m, i, j):
            partner[i] = -1
    pairs = disjoint_pairs(partner, gap)
    merges = pairs.shape[0]
    if merges == 0:
        return 0
    # The codebook's midpoints and the cells moving down (avq.quantizer), and the values with them.
    mapping = merge_kernel(V, size, pairs)
    compact_rows(Q, mapping)
    w = compact_rows(Vm, mapping)
    S[SIZE] = w
    m.C[_model.N_STATES] = w
    S[GEOM] += 1
    rebuild(ag, m, pairs, mapping)
    _model.sweep(m, IP[PlanIntParam.N_BACKUPS])
    return merges
