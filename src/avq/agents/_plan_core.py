"""AVQ with a learned model of its cells (``avq-plan``) as compiled kernels (SPEC §1-§3, and beyond).

The agent acts as AVQ does (SPEC §2: one decision per cell, repeated until the cell changes, a
collision, or the end of the episode). Each aggregate transition ``(i, a) -> j`` of ``k`` steps,
return ``R`` and discount ``gamma ** k`` is recorded in the model of :mod:`avq.agents._model`
(cell = model state) and planned over by prioritized sweeping; the decisions are ε-greedy on
the planned values, which are optimistic for pairs not yet tried.

**Remembered transitions.** The last ``memory`` aggregate transitions are kept with their start
and end observations. When a cell is appended, each remembered transition whose start or end
observation now lies in the new cell is moved there in the model (removed from its old pair and
added to the new one), so that the model always describes the current partition by what was
seen. The oldest transition leaves the model when the memory is full.

**Growth**, both selectable:

* ``collision`` (the paper's rule, SPEC §3): on a collision at ``x`` farther than ``d_min`` from
  the cell's vector and from every vector, append ``x``. (Within ``d_min`` the paper sets
  ``Q[i, a] = chi``; here the model learns what the collision costs instead.)
* ``outcome`` (after parti-game, Moore & Atkeson 1995): when a pair the model knows leads to an
  outcome ``R + gamma**k V(j)`` more than ``split_threshold`` away from the mean outcome of one of
  the successors it has led to before (:func:`avq.agents._model.outcome_spread`), the cell's
  squares disagree about that decision: append the observation where the transition started (if
  farther than ``d_min`` from every vector).

State arrays: ``V`` ``(cap, n)`` the codebook; ``inv_scale``; ``P`` float and ``IP`` int
parameters, ``S`` int and ``F`` float episode state (index names below); ``xs`` the observation
that started the current transition; the memory ``mem_x`` ``(M, 2n)`` start and end observations,
``mem_i`` ``(M, 3)`` action, start cell, end cell (-1: terminal), ``mem_f`` ``(M, 2)`` return and
discount. The model's arrays follow (``*model`` below: :class:`avq.agents._model.ModelArrays`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from avq._kernels import nearest_index
from avq._random import DRAWS_PER_DECISION
from avq.agents import _model
from avq.agents._model import FIRST, push, record, sweep
from avq.agents._td import epsilon_greedy
from avq.rules import APPEND, collision_rule, may_append

# P: float parameters
GAMMA, EPS, DMIN, SPLIT_THRESHOLD = range(4)
N_P = 4
# IP: int parameters
MAX_CELLS, BUDGET, COLLISION_GROWTH, OUTCOME_SPLIT, MEMORY = range(5)
N_IP = 5
# S: int state
SIZE, CELL, ACTION, EP_STEPS, APPENDS, REFUSED, DECISIONS, IN_EPISODE, MEM_N, MEM_POS, SPLITS = range(11)
N_S = 11
# F: float state
RET, DISC, EP_RETURN = range(3)
N_F = 3
#: Statuses of :func:`step` (an action, >= 0, while the episode goes on).
ENDED, NOT_FINITE, NEED_DRAWS, NEED_ROOM = -1, -2, -3, -5
#: Cells a step may append (a collision and a split).
APPENDS_PER_STEP = 2


@njit(cache=True, inline="always")
def distance(V, i: int, x, inv_scale) -> float:
    s = 0.0
    for d in range(x.shape[0]):
        z = (V[i, d] - x[d]) * inv_scale[d]
        s += z * z
    return np.sqrt(s)


@njit(cache=True, inline="always")
def _row_distance(X, t: int, off: int, V, i: int, inv_scale) -> float:
    s = 0.0
    for d in range(V.shape[1]):
        z = (V[i, d] - X[t, off + d]) * inv_scale[d]
        s += z * z
    return np.sqrt(s)


@njit(cache=True)
def append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head,
                p_sa, p_edge, p_next, heap, hpos, prio, C, MP, x) -> int:
    """Append ``x`` as a new cell (a new state of the model, every action unknown), and move every
    remembered transition that starts or ends in it to the new cell. Returns the cell."""
    c = S[SIZE]
    for d in range(x.shape[0]):
        V[c, d] = x[d]
    S[SIZE] = c + 1
    S[APPENDS] += 1
    _model.add_state(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
                     prio, C, MP)
    n = V.shape[1]
    for t in range(S[MEM_N]):
        a, cs, ce = mem_i[t, 0], mem_i[t, 1], mem_i[t, 2]
        ns, ne = cs, ce
        # (strictly nearer: on a tie the lower index, the old cell, stays nearest, as in nearest_index)
        if _row_distance(mem_x, t, 0, V, c, inv_scale) < _row_distance(mem_x, t, 0, V, cs, inv_scale):
            ns = c
        if ce >= 0 and _row_distance(mem_x, t, n, V, c, inv_scale) < _row_distance(mem_x, t, n, V, ce, inv_scale):
            ne = c
        if ns == cs and ne == ce:
            continue
        record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, cs, a,
               mem_f[t, 0], mem_f[t, 1], ce, -1)
        record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, ns, a,
               mem_f[t, 0], mem_f[t, 1], ne, 1)
        push(heap, hpos, prio, C, cs, FIRST)
        push(heap, hpos, prio, C, ns, FIRST)
        mem_i[t, 1] = ns
        mem_i[t, 2] = ne
    push(heap, hpos, prio, C, c, FIRST)
    return c


@njit(cache=True)
def remember(IP, S, xs, x, mem_x, mem_i, mem_f, cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge,
             p_next, heap, hpos, prio, C, a: int, i: int, j: int, R: float, disc: float) -> None:
    """Keep the transition ``(i, a) -> j`` from ``xs`` to ``x`` in the memory; when it is full, the oldest
    transition is forgotten (removed from the model)."""
    t = S[MEM_POS]
    if S[MEM_N] == IP[MEMORY]:
        record(cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, C, mem_i[t, 1],
               mem_i[t, 0], mem_f[t, 0], mem_f[t, 1], mem_i[t, 2], -1)
        push(heap, hpos, prio, C, mem_i[t, 1], FIRST)
    else:
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
def start(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r,
          p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, src, obs) -> int:
    """Start an episode at ``obs`` (the first cell is the first observation, SPEC §3) and decide its first
    action; ``NOT_FINITE`` (changing nothing) for an observation that is NaN or infinite."""
    for d in range(obs.shape[0]):
        if not math.isfinite(obs[d]):
            return NOT_FINITE
    if S[SIZE] == 0:
        append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head,
                    p_sa, p_edge, p_next, heap, hpos, prio, C, MP, obs)
    for d in range(obs.shape[0]):
        xs[d] = obs[d]
    S[EP_STEPS] = 0
    S[APPENDS] = 0
    S[REFUSED] = 0
    S[SPLITS] = 0
    S[DECISIONS] = 1
    S[IN_EPISODE] = 1
    F[RET] = 0.0
    F[DISC] = 1.0
    F[EP_RETURN] = 0.0
    cell, _ = nearest_index(V, S[SIZE], obs, inv_scale)
    S[CELL] = cell
    S[ACTION] = epsilon_greedy(src, Q, cell, P[EPS])
    return S[ACTION]


@njit(cache=True)
def step(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r,
         p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, src, x, r: float, collision: bool, terminated: bool,
         truncated: bool) -> int:
    """One environment step that reached ``x`` with reward ``r``: the action to take next, ``ENDED``, or
    ``NOT_FINITE`` (changing nothing). The caller makes room for :data:`APPENDS_PER_STEP` cells, for
    ``memory + 2`` more edges of the model, and for one decision's draws."""
    if not math.isfinite(r):
        return NOT_FINITE
    for d in range(x.shape[0]):
        if not math.isfinite(x[d]):
            return NOT_FINITE
    i = S[CELL]
    a = S[ACTION]
    S[EP_STEPS] += 1
    F[RET] += F[DISC] * r
    F[DISC] *= P[GAMMA]
    F[EP_RETURN] += r
    j, d2 = nearest_index(V, S[SIZE], x, inv_scale)
    done = terminated or truncated
    if j == i and not (collision or done):
        return a
    # The aggregate transition (i, a) -> j has ended.
    if collision and IP[COLLISION_GROWTH]:
        # SPEC §3's growth on a collision: append x unless it lies within d_min of the cell's vector
        # (or of another vector).
        if collision_rule(distance(V, i, x, inv_scale), np.sqrt(d2), P[DMIN]) == APPEND:
            if S[SIZE] < IP[MAX_CELLS]:
                j = append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, cnt, rsum, head, Q, Vm, e_to, e_next, e_n,
                                e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, x)
            else:
                S[REFUSED] += 1
    cut = truncated and not terminated and j == i and not collision  # (cut short by the time limit: not learned)
    if not cut:
        jm = -1 if terminated else j
        if IP[OUTCOME_SPLIT] and cnt[i, a] >= C[_model.KNOWN]:
            seen = F[RET] + (0.0 if terminated else F[DISC] * Vm[j])
            spread = _model.outcome_spread(cnt, head, Vm, e_to, e_next, e_n, e_disc, e_r, i, a, seen)
            if spread > P[SPLIT_THRESHOLD] and distance(V, i, xs, inv_scale) > P[DMIN]:
                _, ds2 = nearest_index(V, S[SIZE], xs, inv_scale)
                if may_append(np.sqrt(ds2), P[DMIN]):
                    if S[SIZE] < IP[MAX_CELLS]:
                        i = append_cell(V, inv_scale, S, mem_x, mem_i, mem_f, cnt, rsum, head, Q, Vm, e_to, e_next,
                                        e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, xs)
                        S[SPLITS] += 1
                        if jm >= 0 and distance(V, i, x, inv_scale) < distance(V, jm, x, inv_scale):
                            j = jm = i  # (the transition ended in the new cell too)
                    else:
                        S[REFUSED] += 1
        remember(IP, S, xs, x, mem_x, mem_i, mem_f, cnt, rsum, head, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge,
                 p_next, heap, hpos, prio, C, a, i, jm, F[RET], F[DISC])
        _model.observe(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
                       prio, C, MP, i, a, F[RET], F[DISC], jm, IP[BUDGET])
    if done:
        S[IN_EPISODE] = 0
        return ENDED
    S[CELL] = j
    for d in range(x.shape[0]):
        xs[d] = x[d]
    F[RET] = 0.0
    F[DISC] = 1.0
    S[DECISIONS] += 1
    S[ACTION] = epsilon_greedy(src, Q, j, P[EPS])
    return S[ACTION]
