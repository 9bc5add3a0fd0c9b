"""AVQ with a learned model of its cells (``avq-plan``) as compiled kernels (SPEC §1-§3, and beyond).

The agent acts as AVQ does (SPEC §2: one decision per cell, repeated until the cell changes, a
collision, or the end of the episode). Each aggregate transition ``(i, a) -> j`` of ``k`` steps,
return ``R`` and discount ``gamma ** k`` is recorded in the model of :mod:`avq.agents.plan.model`
(cell = model state) and planned over by prioritized sweeping; the decisions are ε-greedy on
the planned values, which are optimistic for pairs not yet tried.

**Remembered transitions.** The last ``memory`` aggregate transitions are kept with their start
and end observations. When the codebook changes, each remembered transition whose start or end
observation now lies in another cell is moved in the model (removed from its old pair and added
to the new one), so that the model describes the current partition by what was seen. Beyond
``memory``, the oldest transition is overwritten: it stays in the model where it was.

**Growth**, both selectable:

* ``collision`` (the paper's rule, SPEC §3): on a collision at ``x`` farther than ``d_min`` from
  the cell's vector and from every vector, append ``x``. (Within ``d_min`` the paper sets
  ``Q[i, a] = chi``; here the model learns what the collision costs instead.)
* ``outcome`` (after parti-game, Moore & Atkeson 1995, and Munos & Moore's splits where the value
  is not smooth): a decision ``a`` in cell ``i`` that the model knows led, from start ``xs``, to
  an outcome ``R + gamma**k V(j)`` that differs from the mean outcome of a successor it led to
  before, from that successor's mean start ``c``, by more than the distance between the starts can
  explain: ``|difference| > split_threshold + L * ||xs - c||``, ``L`` the value's slope (the return
  per unit of scaled distance travelled, estimated from the transitions without collisions unless
  ``value_slope`` is given). The cell's squares then disagree about that decision for a reason of
  structure (a wall, a dead end), not of distance: :func:`split_cell` cuts it in two around the two
  starts. Only outcomes that end in :func:`~avq.agents.plan.model.settled` cells are compared, and only
  when the worse one is below the cell's next best decision (the split would change the policy).
* ``cycle`` (as ``AVQSarsa``'s ``cycle_split``): when two decisions the model knew lead from a cell ``j``
  to another and straight back into ``j``, the square of the return gets a cell of its own.

State arrays: ``V`` ``(cap, n)`` the codebook; ``inv_scale``; ``P`` float and ``IP`` int
parameters, ``S`` int and ``F`` float state (index names below; ``S[GEOM]`` counts the changes of
the codebook, so that a caller may keep the cells of observations it sees again); ``xs`` the observation that
started the current transition; the memory ``mem_x`` ``(M, 2n)`` start and end observations,
``mem_i`` ``(M, 3)`` action, start cell, end cell (-1: terminal), ``mem_f`` ``(M, 2)`` return and
discount; ``e_xs`` ``(edges, n)`` the sum of the starts of each edge's transitions. The model's
arrays follow (:class:`avq.agents.plan.model.ModelArrays`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from avq.quantizer import append_vector, nearest_index, scaled_distance
from avq.agents.plan import model as _model
from avq.agents.plan.model import FIRST, push, record, settled
from avq.agents._td import epsilon_greedy
from avq.rules import (APPEND, closes_cycle, collision_rule, decision_goes_on, outcome_disagrees, split_matters,
                       stayed_too_long)

# P: float parameters
GAMMA, EPS, DMIN, SPLIT_THRESHOLD, SLOPE = range(5)
N_P = 5
# IP: int parameters
MAX_CELLS, BUDGET, COLLISION_GROWTH, OUTCOME_SPLIT, MEMORY, CYCLE_SPLIT, SPLIT_AFTER = range(7)
N_IP = 7
# S: int state
SIZE, CELL, ACTION, EP_STEPS, APPENDS, REFUSED, DECISIONS, IN_EPISODE, MEM_N, MEM_POS, SPLITS, GEOM = range(12)
PREV_CELL, PREV_KNOWN = 12, 13  # the cell of the decision before the current one (-1 at an episode's start),
# and whether that decision was of a known pair
DEC_STEPS = 14  # the primitive steps taken so far with the current decision
DEC_REFUSED = 15  # whether split_after's growth was refused during the current decision (counted once)
N_S = 16
# F: float state: the current transition's return and discount, the episode's return, and the sums
# that estimate the value's slope (return per unit of scaled distance travelled, and how many); then
# n + 1 entries of scratch (F has N_F + n + 1 entries)
RET, DISC, EP_RETURN, SLOPE_SUM, SLOPE_N = range(5)
N_F = 5
#: Statuses of :func:`step` (an action, >= 0, while the episode goes on).
ENDED, NOT_FINITE = -1, -2
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
        best, _ = nearest_index(V, size, X[t, off:off + V.shape[1]], inv_scale)
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
def _record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, e_xs, X, t: int,
            s: int, a: int, r: float, disc: float, s2: int, sign: int) -> None:
    """:func:`avq.agents.plan.model.record`, and the transition's start ``X[t, :n]`` added to (or removed from)
    its edge's sum of starts."""
    e = record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, s, a, r, disc, s2,
               sign)
    for d in range(e_xs.shape[1]):
        e_xs[e, d] += sign * X[t, d]
    if e_n[e] == 0:
        for d in range(e_xs.shape[1]):
            e_xs[e, d] = 0.0


@njit(cache=True)
def relocate(V, inv_scale, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head,
             p_sa, p_edge, p_next, heap, hpos, prio, C, u: int, w: int) -> None:
    """After vectors ``u`` and ``w`` changed (``u = w = -1``: the metric changed), move every remembered
    transition whose start or end cell changed to its new pair in the model (and queue both cells' backups)."""
    n = V.shape[1]
    size = S[SIZE]
    for t in range(S[MEM_N]):
        a, cs, ce = mem_i[t, 0], mem_i[t, 1], mem_i[t, 2]
        ns = _cell_after(V, size, mem_x, t, 0, cs, u, w, inv_scale)
        ne = ce if ce < 0 else _cell_after(V, size, mem_x, t, n, ce, u, w, inv_scale)
        if ns == cs and ne == ce:
            continue
        _record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, e_xs, mem_x, t,
                cs, a, mem_f[t, 0], mem_f[t, 1], ce, -1)
        _record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, e_xs, mem_x, t,
                ns, a, mem_f[t, 0], mem_f[t, 1], ne, 1)
        push(heap, hpos, prio, C, cs, FIRST)
        push(heap, hpos, prio, C, ns, FIRST)
        mem_i[t, 1] = ns
        mem_i[t, 2] = ne
    if u >= 0:
        push(heap, hpos, prio, C, u, FIRST)
        push(heap, hpos, prio, C, w, FIRST)


@njit(cache=True, inline="always")
def _new_cell(V, S, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
              prio, C, MP, x) -> int:
    """Vector ``x`` as a new cell and a new state of the model (every action unknown)."""
    c = append_vector(V, S[SIZE], x)
    S[SIZE] = c + 1
    S[APPENDS] += 1
    S[GEOM] += 1
    _model.add_state(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
                     prio, C, MP)
    return c


@njit(cache=True)
def append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r,
                p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, x) -> int:
    """Append ``x`` as a new cell, and move the remembered transitions that now start or end in it."""
    c = _new_cell(V, S, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                  hpos, prio, C, MP, x)
    relocate(V, inv_scale, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head,
             p_sa, p_edge, p_next, heap, hpos, prio, C, c, c)
    return c


@njit(cache=True)
def split_cell(V, inv_scale, P, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r,
               p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, i: int, a: int, seed_1, seed_2) -> int:
    """Cut cell ``i`` in two around two starts of decision ``a`` whose outcomes disagree: the transitions of
    each successor of ``(i, a)`` go with the nearer of ``seed_1`` and ``seed_2`` to their mean start; the
    cell's vector moves to the mean start of the first group and the mean start of the second becomes a
    new cell. Returns the new
    cell, or -1 (nothing changed) when a group is empty or a mean lies within ``d_min`` of the other or of
    another vector (SPEC §3: no vector within ``d_min`` of another)."""
    n = V.shape[1]
    g1 = np.zeros(n)
    g2 = np.zeros(n)
    n1 = 0
    n2 = 0
    e = head[i, a]
    while e >= 0:  # each successor's transitions go together, by the mean of their starts
        k = e_n[e]
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
        e = e_next[e]
    if n1 == 0 or n2 == 0:
        return -1
    gap = 0.0
    for d in range(n):
        g1[d] /= n1
        g2[d] /= n2
        z = (g1[d] - g2[d]) * inv_scale[d]
        gap += z * z
    if not np.sqrt(gap) > P[DMIN]:
        return -1
    for k in range(S[SIZE]):  # SPEC §3: no vector within d_min of another
        if k != i and (scaled_distance(V, k, g1, inv_scale) <= P[DMIN] or scaled_distance(V, k, g2, inv_scale) <= P[DMIN]):
            return -1
    for d in range(n):
        V[i, d] = g1[d]
    S[GEOM] += 1
    c = _new_cell(V, S, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                  hpos, prio, C, MP, g2)
    relocate(V, inv_scale, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head,
             p_sa, p_edge, p_next, heap, hpos, prio, C, i, c)
    return c


@njit(cache=True, inline="always")
def value_slope(P, F) -> float:
    """``L``: ``value_slope`` if given, else the mean return per unit of scaled distance travelled by the
    transitions without a collision so far (0 before the first)."""
    if P[SLOPE] >= 0.0:
        return P[SLOPE]
    return F[SLOPE_SUM] / F[SLOPE_N] if F[SLOPE_N] > 0 else 0.0


@njit(cache=True, inline="always")
def disagreement(cnt, head, Vm, e_to, e_next, e_n, e_disc, e_r, C, e_xs, inv_scale, i: int, a: int, seen: float,
                 xs, slope: float, out) -> float:
    """The largest excess ``|seen - v_e| - slope * ||xs - c_e||`` over the settled successors ``e`` of
    ``(i, a)`` (``v_e`` the mean outcome of the edge, ``c_e`` its mean start, copied into ``out``), and
    ``-inf`` when there is none. The worse of the two outcomes is ``out``'s last entry."""
    n = xs.shape[0]
    worst = -np.inf
    e = head[i, a]
    while e >= 0:
        k = e_n[e]
        if k > 0 and settled(cnt, C, e_to[e]):
            t = e_to[e]
            v = (e_r[e] + (e_disc[e] * Vm[t] if t >= 0 else 0.0)) / k
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
        e = e_next[e]
    return worst


@njit(cache=True, inline="always")
def remember(IP, S, xs, x, mem_x, mem_i, mem_f, a: int, i: int, j: int, R: float, disc: float) -> None:
    """Keep the transition ``(i, a) -> j`` from ``xs`` to ``x`` in the memory. When it is full, the oldest
    is overwritten: it stays in the model, in the cells it was in, but no longer follows their changes."""
    t = S[MEM_POS]
    if S[MEM_N] < IP[MEMORY]:
        S[MEM_N] += 1
    n = x.shape[0]
    for d in range(n):
        mem_x[t, d] = xs[d]
        mem_x[t, n + d] = x[d]
    mem_i[t, 0] = a
    mem_i[t, 1] = i
    mem_i[t, 2] = j
    mem_f[t, 0] = R
    mem_f[t, 1] = disc
    S[MEM_POS] = (t + 1) % IP[MEMORY]


@njit(cache=True)
def end_record(S, F, rec_row) -> None:
    """The finished episode's record row (the columns of ``avq.agents.avq_sarsa.kernels.R_*``): steps, return, cells,
    appends, merges (none), refused, decisions."""
    rec_row[0] = S[EP_STEPS]
    rec_row[1] = F[EP_RETURN]
    rec_row[2] = S[SIZE]
    rec_row[3] = S[APPENDS]
    rec_row[4] = 0
    rec_row[5] = S[REFUSED]
    rec_row[6] = S[DECISIONS]


@njit(cache=True, inline="always")
def room_left(V, S, C, e_to, cnt) -> bool:
    """Whether the arrays hold what one step may add (:func:`step`'s contract with its caller)."""
    return (S[SIZE] + APPENDS_PER_STEP <= V.shape[0] and C[_model.N_STATES] + APPENDS_PER_STEP <= cnt.shape[0]
            and C[_model.N_EDGES] + APPENDS_PER_STEP * (S[MEM_N] + 1) <= e_to.shape[0])


@njit(cache=True)
def start(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc,
          e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, src, obs) -> int:
    """Start an episode at ``obs`` (the first cell is the first observation, SPEC §3) and decide its first
    action; ``NOT_FINITE`` (changing nothing) for an observation that is NaN or infinite."""
    for d in range(obs.shape[0]):
        if not math.isfinite(obs[d]):
            return NOT_FINITE
    if S[SIZE] == 0:
        _new_cell(V, S, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                  hpos, prio, C, MP, obs)
    for d in range(obs.shape[0]):
        xs[d] = obs[d]
    S[EP_STEPS] = 0
    S[APPENDS] = 0
    S[REFUSED] = 0
    S[SPLITS] = 0
    S[DECISIONS] = 1
    S[IN_EPISODE] = 1
    S[PREV_CELL] = -1
    S[PREV_KNOWN] = 0
    S[DEC_STEPS] = 0
    S[DEC_REFUSED] = 0
    F[RET] = 0.0
    F[DISC] = 1.0
    F[EP_RETURN] = 0.0
    cell, _ = nearest_index(V, S[SIZE], obs, inv_scale)
    S[CELL] = cell
    S[ACTION] = epsilon_greedy(src, Q, cell, P[EPS])
    return S[ACTION]


@njit(cache=True)
def step(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc,
         e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, src, x, r: float, collision: bool,
         terminated: bool, truncated: bool) -> int:
    """One environment step that reached ``x`` with reward ``r``: the action to take next, ``ENDED``, or
    ``NOT_FINITE`` (changing nothing). The caller makes room for :data:`APPENDS_PER_STEP` cells, for
    ``APPENDS_PER_STEP * (remembered + 1)`` more edges of the model, and for one decision's draws."""
    if not math.isfinite(r):
        return NOT_FINITE
    for d in range(x.shape[0]):
        if not math.isfinite(x[d]):
            return NOT_FINITE
    j, d2 = nearest_index(V, S[SIZE], x, inv_scale)
    if goes_on(P, IP, S, F, r, j, d2, collision, terminated or truncated):
        return S[ACTION]
    return end_transition(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to,
                          e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, src, x,
                          collision, terminated, truncated, j, d2)


@njit(cache=True, inline="always")
def goes_on(P, IP, S, F, r: float, j: int, d2: float, collision: bool, done: bool) -> bool:
    """Count a step of reward ``r`` into the current decision's aggregate transition, and whether the
    decision goes on: the step stayed in the cell (``j``, the nearest vector, at squared distance ``d2``),
    without a collision, and the episode goes on (SPEC §2); and (``split_after``) it has not yet stayed
    that many steps in the cell while ``x`` lies farther than ``d_min`` from every vector, where
    :func:`end_transition` gives ``x`` a cell of its own. When it does not, :func:`end_transition` follows."""
    S[EP_STEPS] += 1
    S[DEC_STEPS] += 1
    F[RET] += F[DISC] * r
    F[DISC] *= P[GAMMA]
    F[EP_RETURN] += r
    if not decision_goes_on(j == S[CELL], collision, done):
        return False
    if stayed_too_long(S[DEC_STEPS], IP[SPLIT_AFTER], d2, P[DMIN]):
        if S[SIZE] < IP[MAX_CELLS]:
            return False
        if not S[DEC_REFUSED]:
            S[REFUSED] += 1  # (once per decision)
            S[DEC_REFUSED] = 1
    return True


@njit(cache=True)
def end_transition(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next,
                   e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, src, x, collision: bool,
                   terminated: bool, truncated: bool, j: int, d2: float) -> int:
    """The current decision's aggregate transition ``(i, a) -> j`` ended at ``x`` (a finite observation whose
    nearest vector ``j`` and squared distance ``d2`` are known; the step is counted by :func:`goes_on`):
    record and plan, grow, and the next action or ``ENDED``. The rest of :func:`step`, which a fused loop
    calls only when a transition ends."""
    i = S[CELL]
    a = S[ACTION]
    done = terminated or truncated
    # The aggregate transition (i, a) -> j has ended.
    if j == i and not (collision or done) and IP[SPLIT_AFTER] > 0 and S[DEC_STEPS] >= IP[SPLIT_AFTER]:
        # The decision stayed split_after steps in its cell and x lies farther than d_min from every vector
        # (goes_on): the cell is too large for one decision there; x gets a cell of its own.
        j = append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n,
                        e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, x)
        S[SPLITS] += 1
    travelled = distance_between(xs, x, inv_scale)
    if not collision and travelled > 0.0:
        F[SLOPE_SUM] += abs(F[RET]) / travelled
        F[SLOPE_N] += 1.0
    if collision and IP[COLLISION_GROWTH]:
        # SPEC §3's growth on a collision: append x unless it lies within d_min of the cell's vector
        # (or of another vector).
        if collision_rule(scaled_distance(V, i, x, inv_scale), np.sqrt(d2), P[DMIN]) == APPEND:
            if S[SIZE] < IP[MAX_CELLS]:
                j = append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n,
                                e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, x)
            else:
                S[REFUSED] += 1
    known = cnt[i, a] >= C[_model.KNOWN]  # (before this transition is recorded)
    if IP[CYCLE_SPLIT] and not done and known and S[PREV_KNOWN] and closes_cycle(S[PREV_CELL], i, j):
        # Two decisions the model knew led from cell j to i and straight back into j: a cycle that the
        # greedy policy repeats for ever when the cells' values hold (as AVQSarsa's cycle_split; while
        # exploring, such returns are the way to an untried decision). Give the square of the return a
        # cell of its own (its decisions unknown, so the agent tries them there).
        _, dn2 = nearest_index(V, S[SIZE], x, inv_scale)
        if np.sqrt(dn2) > P[DMIN]:
            if S[SIZE] < IP[MAX_CELLS]:
                j = append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n,
                                e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, x)
                S[SPLITS] += 1
            else:
                S[REFUSED] += 1
    cut = truncated and not terminated and j == i and not collision  # (cut short by the time limit: not learned)
    if not cut:
        jm = -1 if terminated else j
        # Does the outcome disagree with what this decision led to before, more than distance explains?
        # (asked before the transition is recorded)
        n = x.shape[0]
        other = F[N_F:N_F + n + 1]  # (scratch)
        excess = -np.inf
        if IP[OUTCOME_SPLIT] and cnt[i, a] >= C[_model.KNOWN] and settled(cnt, C, jm):
            seen = F[RET] + (0.0 if terminated else F[DISC] * Vm[j])
            excess = disagreement(cnt, head, Vm, e_to, e_next, e_n, e_disc, e_r, C, e_xs, inv_scale, i, a, seen, xs,
                                  value_slope(P, F), other)
        t = S[MEM_POS]
        remember(IP, S, xs, x, mem_x, mem_i, mem_f, a, i, jm, F[RET], F[DISC])
        _record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, e_xs, mem_x, t, i, a,
                F[RET], F[DISC], jm, 1)
        if outcome_disagrees(excess, P[SPLIT_THRESHOLD]):
            bar = -np.inf  # the value of the next best decision in i
            for b in range(Q.shape[1]):
                if b != a and Q[i, b] > bar:
                    bar = Q[i, b]
            if split_matters(other[n], bar):
                if S[SIZE] < IP[MAX_CELLS]:
                    if split_cell(V, inv_scale, P, S, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next,
                                  e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, i, a, xs,
                                  other[:n]) >= 0:
                        S[SPLITS] += 1
                        j, _ = nearest_index(V, S[SIZE], x, inv_scale)  # (the vectors moved)
                else:
                    S[REFUSED] += 1
        _model.settle(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
                      prio, C, MP, mem_i[t, 1], IP[BUDGET])
    if done:
        S[IN_EPISODE] = 0
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
    S[ACTION] = epsilon_greedy(src, Q, j, P[EPS])
    return S[ACTION]
