"""AVQ with a learned model of its cells (``avq-plan``) as compiled kernels: the step and the growth
(docs: explanation/paper.md, Setting, Acting, Growing; and beyond).

The agent acts as AVQ does (one decision per cell, repeated until the cell changes, a collision, or
the end of the episode; docs: explanation/paper.md, Acting). Each aggregate transition ``(i, a) -> j`` of ``k`` steps,
return ``R`` and discount ``gamma ** k`` is recorded in the model of :mod:`avq.agents.plan.model`
(cell = model state) and planned over by prioritized sweeping; the decisions are ε-greedy on
the planned values, which are optimistic for pairs not yet tried.

**Remembered transitions** (:mod:`avq.agents.plan.memory`): the model follows the last ``memory``
aggregate transitions into the cells they now lie in when the codebook changes.

**Growth**, each selectable:

* ``collision`` (the paper's rule; docs: explanation/paper.md, Growing): on a collision at ``x``
  farther than ``d_min`` from the cell's vector and from every vector, append ``x``. (Within
  ``d_min`` the paper sets ``Q[i, a] = chi``; here the model learns what the collision costs instead.)
* ``outcome`` (after parti-game, Moore & Atkeson 1995, and Munos & Moore's splits where the value
  is not smooth): a decision ``a`` in cell ``i`` that the model knows led, from start ``xs``, to
  an outcome ``R + gamma**k V(j)`` that differs from the mean outcome of a successor it led to
  before, from that successor's mean start ``c``, by more than the distance between the starts can
  explain: ``|difference| > split_threshold + L * ||xs - c||``, ``L`` the value's slope (the return
  per unit of scaled distance travelled, estimated from the transitions without collisions unless
  ``value_slope`` is given). The cell's squares then disagree about that decision for a reason of
  structure (a wall, a dead end), not of distance: :func:`split_cell` cuts it in two around the two
  starts. Only outcomes that end in settled cells are compared (``"unsettled"``: or in cells whose values owe
  nothing to optimism, :func:`~avq.agents.plan.explore.owes_no_optimism`, as near a goal whose way is worth more
  than ``v_opt``, where cells may never settle), and only
  when the worse one is below the cell's next best decision (the split would change the policy).
* ``cycle`` (as ``AVQSarsa``'s ``cycle_split``): when two decisions the model knew lead from a cell ``j``
  to another and straight back into ``j``, the square of the return gets a cell of its own.

The kernels take ``ag``, the agent's arrays (:class:`avq.agents.plan.state.PlanArrays`: the codebook,
the parameters, the state, the memory), and ``m``, the model's
(:class:`avq.agents.plan.model.ModelArrays`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from avq.agents.plan import model as _model
from avq.agents.plan.explore import decide, owes_no_optimism
from avq.agents.plan.memory import record_with_start, relocate, remember, start_after_growth, successor
from avq.agents.plan.merge import merge_pass, value_slope
from avq.agents.plan.model import CONT, ModelArrays, known as known_pair, settled
from avq.agents.plan.resolution import decision_floor, refine_when_settled
from avq.agents.plan.state import (
    ACTION,
    APPENDS,
    CELL,
    DEC_REFUSED,
    DEC_STEPS,
    DECISIONS,
    DISC,
    EP_RETURN,
    EP_STEPS,
    F_AT_START,
    GEOM,
    IN_EPISODE,
    MEM_N,
    MEM_POS,
    MERGES,
    N_F,
    PREV_CELL,
    PREV_KNOWN,
    REFUSED,
    RET,
    S_AT_START,
    SIZE,
    SLOPE_N,
    SLOPE_SUM,
    SPLITS,
    PlanArrays,
    PlanIntParam,
    PlanParam,
)
from avq.quantizer import append_vector, nearest_index, scaled_distance
from avq.rules import (
    APPEND,
    closes_cycle,
    collision_rule,
    decision_goes_on,
    outcome_disagrees,
    split_matters,
    stayed_too_long,
)

#: Statuses of :func:`step` (an action, >= 0, while the episode goes on).
ENDED, NOT_FINITE = -1, -2
#: ``IP[OUTCOME_SPLIT]`` of ``outcome_split="unsettled"`` (True is 1).
UNSETTLED = 2
#: Cells a step may append (a collision and a split).
APPENDS_PER_STEP = 2


@njit(cache=True, inline="always")
def distance_between(x, y, inv_scale) -> float:
    s = 0.0
    for d in range(x.shape[0]):
        z = (x[d] - y[d]) * inv_scale[d]
        s += z * z
    return np.sqrt(s)


@njit(cache=True, inline="always")
def _new_cell(ag: PlanArrays, m: ModelArrays, x) -> int:
    """Vector ``x`` as a new cell and a new state of the model (every action unknown)."""
    S = ag.S
    c = append_vector(ag.V, S[SIZE], x)
    S[SIZE] = c + 1
    S[APPENDS] += 1
    S[GEOM] += 1
    _model.add_state(m)
    return c


@njit(cache=True)
def append_cell(ag: PlanArrays, m: ModelArrays, x) -> int:
    """Append ``x`` as a new cell, and move the remembered transitions that now start or end in it."""
    c = _new_cell(ag, m, x)
    relocate(ag, m, c, c)
    return c


@njit(cache=True)
def split_cell(ag: PlanArrays, m: ModelArrays, i: int, a: int, seed_1, seed_2, axis_share: float, floor: float) -> int:
    """Cut cell ``i`` in two around two starts of decision ``a`` whose outcomes disagree: the transitions of
    each successor of ``(i, a)`` go with the nearer of ``seed_1`` and ``seed_2`` to their mean start; the
    cell's vector moves to the mean start of the first group and the mean start of the second becomes a
    new cell. Where one axis carries at least ``axis_share`` of the squared scaled distance between the two
    means (0: always; below 0: never), the cut is across that axis alone: the two vectors are the cell's own,
    moved along that axis to the two means' coordinates on it. Returns the new
    cell, or -1 (nothing changed) when a group is empty or a mean lies within ``floor`` (``d_min``, or the outcome
    split's :func:`~avq.agents.plan.resolution.decision_floor`) of the other or of another vector (docs:
    explanation/paper.md, Growing)."""
    V, inv_scale, e_xs = ag.V, ag.inv_scale, ag.e_xs
    n = V.shape[1]
    g1 = np.zeros(n)
    g2 = np.zeros(n)
    n1 = 0
    n2 = 0
    e = m.head[i, a]
    while e >= 0:  # each successor's transitions go together, by the mean of their starts
        k = m.e_n[e]
        if k > 0:
            d1 = 0.0
            d2 = 0.0
            for d in range(n):
                z1 = (e_xs[e, d] / k - seed_1[d]) * inv_scale[d]
                z2 = (e_xs[e, d] / k - seed_2[d]) * inv_scale[d]
                d1 += z1 * z1
                d2 += z2 * z2
            if d1 <= d2:
                n1 += k
                for d in range(n):
                    g1[d] += e_xs[e, d]
            else:
                n2 += k
                for d in range(n):
                    g2[d] += e_xs[e, d]
        e = m.e_next[e]
    if n1 == 0 or n2 == 0:
        return -1
    gap = 0.0
    for d in range(n):
        g1[d] /= n1
        g2[d] /= n2
        z = (g1[d] - g2[d]) * inv_scale[d]
        gap += z * z
    axis = 0  # (the axis that carries the most of the gap)
    for d in range(n):
        if abs(g1[d] - g2[d]) * inv_scale[d] > abs(g1[axis] - g2[axis]) * inv_scale[axis]:
            axis = d
    along = ((g1[axis] - g2[axis]) * inv_scale[axis]) ** 2
    if axis_share >= 0.0 and along >= axis_share * gap:
        gap = along
        for d in range(n):
            if d != axis:
                g1[d] = V[i, d]
                g2[d] = V[i, d]
    if not np.sqrt(gap) > floor:
        return -1
    for k in range(ag.S[SIZE]):  # no vector within the floor of another (docs: explanation/paper.md, Growing)
        if k != i and (scaled_distance(V, k, g1, inv_scale) <= floor or scaled_distance(V, k, g2, inv_scale) <= floor):
            return -1
    for d in range(n):
        V[i, d] = g1[d]
    ag.S[GEOM] += 1
    c = _new_cell(ag, m, g2)
    relocate(ag, m, i, c)
    return c


@njit(cache=True)
def cut_at_collision(ag: PlanArrays, m: ModelArrays, i: int, a: int, x) -> int:
    """``collision_cut``: decision ``a`` collided at ``x`` in cell ``i`` (its transition recorded), where it
    was also seen to leave the cell without a collision. Cut ``i`` across one axis between ``x`` and the mean
    start of the decision's most frequent successor other than ``i`` (:func:`split_cell` with ``axis_share``
    0). Returns the new cell, or -1 (nothing changed: no such successor, or :func:`split_cell` refused)."""
    best, most = -1, 0
    e = m.head[i, a]
    while e >= 0:
        if m.e_to[e] != i and m.e_n[e] > most:
            best, most = e, m.e_n[e]
        e = m.e_next[e]
    if best < 0:
        return -1
    return split_cell(ag, m, i, a, x, ag.e_xs[best] / most, 0.0, ag.P[PlanParam.D_MIN])


@njit(cache=True, inline="always")
def compared(m: ModelArrays, s: int, mode: int) -> bool:
    """Whether the outcome split compares outcomes that end in ``s``: settled, or (``outcome_split`` "unsettled",
    ``mode`` 2) its value owes nothing to optimism."""
    return owes_no_optimism(m, s) if mode == UNSETTLED else settled(m, s)


@njit(cache=True, inline="always")
def disagreement(ag: PlanArrays, m: ModelArrays, i: int, a: int, seen: float, slope: float, out) -> float:
    """The largest excess ``|seen - v_e| - slope * ||xs - c_e||`` over the successors ``e`` of ``(i, a)`` that
    the split compares (:func:`compared`; ``xs`` the current transition's start, ``v_e`` the mean outcome of the
    edge, ``c_e`` its mean start, copied into ``out``), and ``-inf`` when there is none. The worse of the two
    outcomes is ``out``'s last entry."""
    xs, e_xs, inv_scale = ag.xs, ag.e_xs, ag.inv_scale
    n = xs.shape[0]
    worst = -np.inf
    e = m.head[i, a]
    while e >= 0:
        k = m.e_n[e]
        if k > 0 and compared(m, m.e_to[e], ag.IP[PlanIntParam.OUTCOME_SPLIT]):
            t = m.e_to[e]
            later = m.V[t] if t >= 0 else (m.Q[i, a] if t == CONT else 0.0)  # (CONT: the decision goes on)
            v = (m.e_r[e] + m.e_disc[e] * later) / k
            dist = 0.0
            for d in range(n):
                z = (xs[d] - e_xs[e, d] / k) * inv_scale[d]
                dist += z * z
            excess = abs(seen - v) - slope * np.sqrt(dist)
            if excess > worst:
                worst = excess
                for d in range(n):
                    out[d] = e_xs[e, d] / k
                out[n] = min(seen, v)
        e = m.e_next[e]
    return worst


@njit(cache=True)
def end_record(S, F, rec_row) -> None:
    """The finished episode's record row (the columns of ``avq.agents._maze_loop.R_*``): steps, return, cells,
    appends, merges, refused, decisions."""
    rec_row[0] = S[EP_STEPS]
    rec_row[1] = F[EP_RETURN]
    rec_row[2] = S[SIZE]
    rec_row[3] = S[APPENDS]
    rec_row[4] = S[MERGES]
    rec_row[5] = S[REFUSED]
    rec_row[6] = S[DECISIONS]


@njit(cache=True, inline="always")
def room_left(ag: PlanArrays, m: ModelArrays) -> bool:
    """Whether the arrays hold what one step may add (:func:`step`'s contract with its caller)."""
    S = ag.S
    return (
        S[SIZE] + APPENDS_PER_STEP <= ag.V.shape[0]
        and m.C[_model.N_STATES] + APPENDS_PER_STEP <= m.cnt.shape[0]
        and m.C[_model.N_EDGES] + APPENDS_PER_STEP * (S[MEM_N] + 1) <= m.e_to.shape[0]
    )


@njit(cache=True)
def start(ag: PlanArrays, m: ModelArrays, src, obs) -> int:
    """Start an episode at ``obs`` (the first cell is the first observation; docs: explanation/paper.md,
    Growing) and decide its first action; ``NOT_FINITE`` (changing nothing) for an observation that is NaN
    or infinite."""
    S, F = ag.S, ag.F
    for d in range(obs.shape[0]):
        if not math.isfinite(obs[d]):
            return NOT_FINITE
    if S[SIZE] == 0:
        _new_cell(ag, m, obs)
    for d in range(obs.shape[0]):
        ag.xs[d] = obs[d]
    for k, v in S_AT_START:
        S[k] = v
    for k, f in F_AT_START:
        F[k] = f
    cell, _ = nearest_index(ag.V, S[SIZE], obs, ag.inv_scale)
    S[CELL] = cell
    S[ACTION] = decide(ag, m, src, cell, obs)
    return S[ACTION]


@njit(cache=True)
def step(ag: PlanArrays, m: ModelArrays, src, x, r: float, collision: bool, terminated: bool, truncated: bool) -> int:
    """One environment step that reached ``x`` with reward ``r``: the action to take next, ``ENDED``, or
    ``NOT_FINITE`` (changing nothing). The caller makes room for :data:`APPENDS_PER_STEP` cells, for
    ``APPENDS_PER_STEP * (remembered + 1)`` more edges of the model, and for one decision's draws."""
    if not math.isfinite(r):
        return NOT_FINITE
    for d in range(x.shape[0]):
        if not math.isfinite(x[d]):
            return NOT_FINITE
    j, d2 = nearest_index(ag.V, ag.S[SIZE], x, ag.inv_scale)
    if goes_on(ag, r, j, d2, collision, terminated or truncated):
        return ag.S[ACTION]
    return end_transition(ag, m, src, x, collision, terminated, truncated, j, d2)


@njit(cache=True, inline="always")
def goes_on(ag: PlanArrays, r: float, j: int, d2: float, collision: bool, done: bool) -> bool:
    """Count a step of reward ``r`` into the current decision's aggregate transition, and whether the
    decision goes on: the step stayed in the cell (``j``, the nearest vector, at squared distance ``d2``),
    without a collision, and the episode goes on (docs: explanation/paper.md, Acting); and
    (``split_after``) it has not yet stayed that many steps in the cell while ``x`` lies farther than the
    floor (:func:`~avq.agents.plan.resolution.decision_floor`) from every vector, where :func:`end_transition`
    gives ``x`` a cell of its own. When it does not, :func:`end_transition` follows."""
    P, IP, S, F = ag.P, ag.IP, ag.S, ag.F
    S[EP_STEPS] += 1
    S[DEC_STEPS] += 1
    F[RET] += F[DISC] * r
    F[DISC] *= P[PlanParam.GAMMA]
    F[EP_RETURN] += r
    if not decision_goes_on(j == S[CELL], collision, done):
        return False
    if stayed_too_long(S[DEC_STEPS], IP[PlanIntParam.SPLIT_AFTER], d2, decision_floor(P, S)):
        if S[SIZE] < IP[PlanIntParam.MAX_CELLS]:
            return False
        if not S[DEC_REFUSED]:
            S[REFUSED] += 1  # (once per decision)
            S[DEC_REFUSED] = 1
    return True


@njit(cache=True)
def end_transition(
    ag: PlanArrays, m: ModelArrays, src, x, collision: bool, terminated: bool, truncated: bool, j: int, d2: float
) -> int:
    """The current decision's aggregate transition ``(i, a) -> j`` ended at ``x`` (a finite observation whose
    nearest vector ``j`` and squared distance ``d2`` are known; the step is counted by :func:`goes_on`):
    record and plan, grow, and the next action or ``ENDED``. The rest of :func:`step`, which a fused loop
    calls only when a transition ends."""
    V, inv_scale, P, IP, S, F, xs = ag.V, ag.inv_scale, ag.P, ag.IP, ag.S, ag.F, ag.xs
    Q = m.Q
    max_cells = IP[PlanIntParam.MAX_CELLS]
    i = S[CELL]
    a = S[ACTION]
    done = terminated or truncated
    grown_from = S[SIZE]  # (the cells appended from here on are new in this step)
    # The aggregate transition (i, a) -> j has ended.
    split_after = IP[PlanIntParam.SPLIT_AFTER]
    if j == i and not (collision or done) and split_after > 0 and S[DEC_STEPS] >= split_after:
        # The decision stayed split_after steps in its cell and x lies farther than the floor from every vector
        # (goes_on): the cell is too large for one decision there; x gets a cell of its own.
        j = append_cell(ag, m, x)
        S[SPLITS] += 1
    travelled = distance_between(xs, x, inv_scale)
    if not collision and travelled > 0.0:
        F[SLOPE_SUM] += abs(F[RET]) / travelled
        F[SLOPE_N] += 1.0
    if collision and IP[PlanIntParam.COLLISION_GROWTH]:
        # The paper's growth on a collision (docs: explanation/paper.md, Growing): append x unless it lies
        # within d_min of the cell's vector (or of another vector).
        if collision_rule(scaled_distance(V, i, x, inv_scale), np.sqrt(d2), P[PlanParam.D_MIN]) == APPEND:
            if S[SIZE] < max_cells:
                j = append_cell(ag, m, x)
            else:
                S[REFUSED] += 1
    known = known_pair(m, i, a)  # (before this transition is recorded)
    if IP[PlanIntParam.CYCLE_SPLIT] and not done and known and S[PREV_KNOWN] and closes_cycle(S[PREV_CELL], i, j):
        # Two decisions the model knew led from cell j to i and straight back into j: a cycle that the
        # greedy policy repeats for ever when the cells' values hold (as AVQSarsa's cycle_split; while
        # exploring, such returns are the way to an untried decision). Give the square of the return a
        # cell of its own (its decisions unknown, so the agent tries them there).
        _, dn2 = nearest_index(V, S[SIZE], x, inv_scale)
        if np.sqrt(dn2) > P[PlanParam.D_MIN]:
            if S[SIZE] < max_cells:
                j = append_cell(ag, m, x)
                S[SPLITS] += 1
            else:
                S[REFUSED] += 1
    cut = truncated and not terminated and j == i and not collision  # (cut short by the time limit: not learned)
    if not cut:
        jm = -1 if terminated else j
        # Does the outcome disagree with what this decision led to before, more than distance explains?
        # (asked before the transition is recorded)
        n = x.shape[0]
        other = F[N_F : N_F + n + 1]  # (scratch)
        excess = -np.inf
        if IP[PlanIntParam.OUTCOME_SPLIT] and known_pair(m, i, a) and compared(m, jm, IP[PlanIntParam.OUTCOME_SPLIT]):
            seen = F[RET] + (0.0 if terminated else F[DISC] * m.V[j])
            excess = disagreement(ag, m, i, a, seen, value_slope(P, F), other)
        t = S[MEM_POS]
        # (a crossing: it ended only because the cell changed; where its two ends come to lie in one cell, it goes
        # on: avq.agents.plan.memory.successor; COMPOSED with merging or compose_crossings, HELD with "noise")
        crossing = 0 if collision or terminated or j == i else IP[PlanIntParam.COMPOSE_CROSSINGS]
        remember(ag, x, a, i, jm, F[RET], F[DISC], crossing)
        start = i
        if P[PlanParam.RHO] >= 0.0 and S[SIZE] > grown_from:
            # With merging, every remembered transition lies in the cell its start lies in (the merge pass's
            # rebuild relies on it): a cell appended in this step may hold the decision's start.
            start = start_after_growth(ag, t, i, grown_from)
            ag.mem_i[t, 1] = start
        record_with_start(m, ag.e_xs, ag.mem_x, t, start, a, F[RET], F[DISC], successor(start, jm, crossing), 1)
        if collision and IP[PlanIntParam.COLLISION_CUT]:
            if S[SIZE] < max_cells:
                if cut_at_collision(ag, m, i, a, x) >= 0:
                    S[SPLITS] += 1
                    j, _ = nearest_index(V, S[SIZE], x, inv_scale)  # (the vectors moved)
                    excess = -np.inf  # (the cell's transitions were cut already)
            else:
                S[REFUSED] += 1
        if outcome_disagrees(excess, P[PlanParam.SPLIT_THRESHOLD]):
            bar = -np.inf  # the value of the next best decision in i
            for b in range(Q.shape[1]):
                if b != a and Q[i, b] > bar:
                    bar = Q[i, b]
            if split_matters(other[n], bar):
                if S[SIZE] < max_cells:
                    if split_cell(ag, m, i, a, xs, other[:n], P[PlanParam.AXIS_SHARE], decision_floor(P, S)) >= 0:
                        S[SPLITS] += 1
                        j, _ = nearest_index(V, S[SIZE], x, inv_scale)  # (the vectors moved)
                else:
                    S[REFUSED] += 1
        _model.settle(m, ag.mem_i[t, 1], IP[PlanIntParam.N_BACKUPS])
    if done:
        S[IN_EPISODE] = 0
        S[MERGES] = merge_pass(ag, m)  # (docs: explanation/paper.md, Merging; avq.agents.plan.merge)
        refine_when_settled(ag, m, IP[PlanIntParam.FINER_WHEN_SETTLED])
        return ENDED
    S[PREV_CELL] = i
    S[PREV_KNOWN] = known
    S[CELL] = j
    for d in range(x.shape[0]):
        xs[d] = x[d]
    F[RET] = 0.0
    F[DISC] = 1.0
    S[DEC_STEPS] = 0
    S[DEC_REFUSED] = 0
    S[DECISIONS] += 1
    S[ACTION] = decide(ag, m, src, j, x)
    return S[ACTION]
