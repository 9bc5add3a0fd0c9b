"""AVQ Sarsa(λ) as compiled kernels on packed arrays (SPEC §2-§5).

One implementation of the agent's rules serves both paths:

* the generic path (any Gymnasium environment) steps the environment in Python
  and makes one compiled call per step, :func:`generic_step` (:func:`observe`,
  then at the end of an aggregate transition :func:`decide` and :func:`learn`);
* the fused paths (``avq/GridMaze-v0``, ``avq/RobotMaze-v0``, :mod:`avq.agents.avq_sarsa.fused`)
  run the environment's dynamics and these same kernels inside one compiled loop.

The update rules themselves (ε-greedy, the TD error, the Sarsa(λ) update) are those of
:mod:`avq.agents._td`, and the merge criteria those of :mod:`avq.rules`. The random
stream is the agent's ``numpy.random.Generator``: the fused loops draw from it directly,
the generic path through its :class:`~avq._random.RawStream`, which gives the very same
numbers; both make the same draws in the same order, so both paths give identical results.

State lives in preallocated arrays: ``V`` codebook ``(cap, n)``, ``Q`` and ``E``
``(cap, m)``, ``born`` ``(cap, 2 + m)`` the episode (1-based) that created each cell,
the last episode in which the agent took a decision in it, and how many decisions
it took there with each action; ``act`` ``(cap + 1,)`` the rows whose traces are
non-zero this episode (``act[0]`` of them), so that an update touches only those;
``pc`` ``(cap + 1, 2)`` the mutual-nearest pairs of the current geometry
(``pc[0] = (geometry version, count)``), recomputed only after the codebook
changed; parameters in ``P`` (float) and ``IP`` (int); the agent's position in
the episode in ``S`` (int) and ``F`` (float). Index names are the module
constants below. Skipping rows whose traces are zero and reusing the pairs change
no result: those rows would be updated by ``0 * step``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from avq._numba import borrowed
from avq.quantizer import (append_vector, compact_rows, merge_kernel, mutual_nearest_pairs_kernel, nearest_index,
                           nearest_pairs_kernel, scaled_distance)
from avq._random import DRAWS_PER_DECISION
from avq.agents._maze_loop import N_R, R_APPENDS, R_CELLS, R_DECISIONS, R_MERGES, R_REFUSED, R_RETURN, R_STEPS  # noqa: F401
from avq.agents._td import clear_traces, epsilon_greedy, greedy_ties, sarsa_lambda, sarsa_td_error
from avq.rules import APPEND as APPEND_OUTCOME
from avq.rules import CHI as CHI_OUTCOME
from avq.rules import (closes_cycle, collision_rule, collision_split, decision_goes_on, may_append,
                       mean_square_difference, merge_profiles, old_enough, repeat_limit_reached, reward_jump,
                       same_greedy_action, similar_profiles, stale_cell, value_jump)

# P: float parameters
ALPHA, LAM, GAMMA, EPS, DMIN, RHO, CHI, QINIT, VTRIG, RTRIG, EPS0, EPS_DECAY, EPS_MIN, ADAPT = range(14)
ALPHA0, ALPHA_DECAY, ALPHA_MIN, BONUS = range(14, 18)
N_P = 18
# IP: int parameters
REPLACING, MERGE_EVERY, MERGE_AGE, MAX_CELLS, MERGE_SAME_ACTION, COLLISION_SPLIT, MERGE_PAIRS, CYCLE_SPLIT = range(8)
PRUNE_AFTER, MAKE_ROOM, MAX_REPEAT = 8, 9, 10
N_IP = 11
# S: int state
SIZE, CELL, ACTION, EP_STEPS, APPENDS, REFUSED, DECISIONS, EPISODES, IN_EPISODE, GEOM = range(10)
PREV_CELL, PREV_GREEDY = 10, 11  # the cell of the decision before the current one, and whether it was greedy
REPEATS = 12  # the primitive steps taken so far with the current decision
N_S = 13
# F: float state
RET, DISC, EP_RETURN, PREV_R = range(4)
N_F = 4
# Returned by observe() for an observation or reward that is NaN or infinite.
NOT_FINITE = -2


@njit(cache=True, inline="always")
def _may_append(dist_nearest: float, P, IP, S) -> bool:
    """SPEC §3: never within d_min of an existing vector; never beyond max_cells (counted)."""
    if not may_append(dist_nearest, P[DMIN]):
        return False
    if S[SIZE] >= IP[MAX_CELLS]:
        S[REFUSED] += 1
        return False
    return True


@njit(cache=True, inline="always")
def _append(V, Q, E, born, S, x, parent: int) -> int:
    """Append ``x`` as a cell whose profile is a copy of ``parent``'s (SPEC §3)."""
    c = append_vector(V, S[SIZE], x)
    # Element loops, not slices: slice assignment drags shape-error formatting into the hot path.
    for b in range(Q.shape[1]):
        Q[c, b] = Q[parent, b]
        E[c, b] = 0.0
    born[c, 0] = S[EPISODES] + 1
    born[c, 1] = S[EPISODES] + 1
    for b in range(2, born.shape[1]):
        born[c, b] = 0
    S[SIZE] = c + 1
    S[APPENDS] += 1
    S[GEOM] += 1
    return c


@njit(cache=True, inline="always")
def bonus_values(Q, born, P, j: int, out) -> None:
    """``out[0] = Q[j] + explore_bonus / sqrt(1 + n)``, ``n`` the decisions taken with each action in
    cell ``j``: the values that count-based exploration takes its greedy decision on."""
    for b in range(Q.shape[1]):
        out[0, b] = Q[j, b] + P[BONUS] / np.sqrt(1.0 + born[j, 2 + b])


@njit(cache=True, inline="always")
def begin_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x) -> int:
    """Start an episode at observation ``x``; return its cell. The caller then picks the action."""
    if S[SIZE] == 0:
        # SPEC §3: the codebook starts with the very first observation.
        for d in range(x.shape[0]):
            V[0, d] = x[d]
        for b in range(Q.shape[1]):
            Q[0, b] = P[QINIT]
            E[0, b] = 0.0
        born[0, 0] = 0
        born[0, 1] = 0
        S[SIZE] = 1
        S[GEOM] += 1
    clear_traces(E, act)
    S[EP_STEPS] = 0
    S[APPENDS] = 0
    S[REFUSED] = 0
    S[DECISIONS] = 1
    S[IN_EPISODE] = 1
    S[PREV_CELL] = -1
    S[PREV_GREEDY] = 0
    S[REPEATS] = 0
    F[RET] = 0.0
    F[DISC] = 1.0
    F[EP_RETURN] = 0.0
    F[PREV_R] = 0.0
    cell, _ = nearest_index(V, S[SIZE], x, inv_scale)
    S[CELL] = cell
    born[cell, 1] = S[EPISODES] + 1
    return cell


@njit(cache=True)
def observe(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, r: float, collision: bool, done: bool) -> int:
    """Account for one primitive step that reached ``x`` with reward ``r``.

    Returns -1 while the aggregate transition goes on (same cell, no collision, not
    ``done``, fewer than ``max_repeat`` steps), else the cell ``j`` it ends in, after
    the growth rules of SPEC §3 that act at once (collision; reward jump). Returns ``NOT_FINITE``, changing
    nothing, when ``x`` or ``r`` is NaN or infinite.
    """
    if not math.isfinite(r):
        return NOT_FINITE
    for d in range(x.shape[0]):
        if not math.isfinite(x[d]):
            return NOT_FINITE
    j, d2 = nearest_index(V, S[SIZE], x, inv_scale)
    return observe_at(V, Q, E, born, S, F, P, IP, inv_scale, x, r, collision, done, j, np.sqrt(d2))


@njit(cache=True, inline="always")
def observe_at(V, Q, E, born, S, F, P, IP, inv_scale, x, r, collision, done, j, dist_j) -> int:
    """:func:`observe` with the nearest vector ``j`` of ``x`` and its distance already known."""
    i = S[CELL]
    a = S[ACTION]
    S[EP_STEPS] += 1
    S[REPEATS] += 1
    F[RET] += F[DISC] * r
    F[DISC] *= P[GAMMA]
    F[EP_RETURN] += r
    if P[RTRIG] > 0.0:
        jump = reward_jump(r, F[PREV_R], S[EP_STEPS], P[RTRIG])
        F[PREV_R] = r
        if jump and not collision and _may_append(dist_j, P, IP, S):
            j = _append(V, Q, E, born, S, x, i)
    if P[ADAPT] > 0.0 and not collision:
        # Beyond the paper: move the vector of x's cell toward x (online k-means, rate adapt_rate).
        for d in range(x.shape[0]):
            V[j, d] += P[ADAPT] * (x[d] - V[j, d])
        S[GEOM] += 1
    # SPEC §2: the decision goes on while the cell stays the same; beyond the paper, for at most max_repeat
    # steps, after which it ends in that same cell and learn() takes it as any other aggregate transition.
    if decision_goes_on(j == i, collision, done) and not repeat_limit_reached(S[REPEATS], IP[MAX_REPEAT]):
        return -1
    if collision:
        # SPEC §3, collision rule (avq.rules.collision_rule).
        dist_i = dist_j if j == i else scaled_distance(V, i, x, inv_scale)
        outcome = collision_rule(dist_i, dist_j, P[DMIN])
        if outcome == CHI_OUTCOME and IP[COLLISION_SPLIT] and S[SIZE] < IP[MAX_CELLS] \
                and collision_split(dist_i, np.argmax(Q[i]) == a, Q[i, a], P[CHI]):
            # Beyond the paper: the cell's greedy action hit a wall here but is still the best one
            # elsewhere in the cell; instead of condemning it for the whole cell, split x off.
            j = _append(V, Q, E, born, S, x, i)
            Q[j, a] = P[CHI]
        elif outcome == CHI_OUTCOME:
            Q[i, a] = P[CHI]
        elif outcome == APPEND_OUTCOME and _may_append(dist_j, P, IP, S):
            j = _append(V, Q, E, born, S, x, i)
            Q[j, a] = P[CHI]  # the rule at the new cell itself: ||y_c - x|| = 0 <= d_min
    return j


@njit(cache=True, inline="always")
def learn(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, j: int, a_next: int, terminated: bool, done: bool) -> int:
    """SPEC §5: the Sarsa(λ) update of the transition ``(S[CELL], S[ACTION]) -> (j, a_next)``.

    Then the optional value-change trigger (SPEC §3). Moves the agent to the next
    decision and returns its cell.
    """
    i = S[CELL]
    a = S[ACTION]
    born[i, 2 + a] += 1  # one more decision (i, a)
    greedy = True  # was the decision (i, a) greedy? (a best action of Q[i], ties included; cycle split only)
    if IP[CYCLE_SPLIT]:
        for b in range(Q.shape[1]):
            if Q[i, b] > Q[i, a]:
                greedy = False
                break
    if terminated:
        delta = sarsa_td_error(Q[i, a], F[RET], F[DISC], 0.0, True)
    else:
        delta = sarsa_td_error(Q[i, a], F[RET], F[DISC], Q[j, a_next], False)
    sarsa_lambda(Q, E, act, i, a, delta, P[ALPHA], F[DISC] * P[LAM], IP[REPLACING] != 0)
    appended = False
    if value_jump(delta, P[VTRIG]):
        if _may_append(scaled_distance(V, j, x, inv_scale), P, IP, S):
            j = _append(V, Q, E, born, S, x, j)
            appended = True
    if IP[CYCLE_SPLIT] and not (done or appended) and greedy and S[PREV_GREEDY] and closes_cycle(S[PREV_CELL], i, j):
        # Beyond the paper: two greedy decisions led from cell j to i and back into j, a cycle
        # that the greedy policy would repeat forever: the cell j is wrong for part of it.
        # Split off the square of the return (x, unless it is j's own vector).
        if scaled_distance(V, j, x, inv_scale) > 0.0:
            if S[SIZE] < IP[MAX_CELLS]:
                j = _append(V, Q, E, born, S, x, j)
            else:
                S[REFUSED] += 1
    S[PREV_CELL] = i
    S[PREV_GREEDY] = greedy
    S[CELL] = j
    born[j, 1] = S[EPISODES] + 1
    S[ACTION] = a_next
    S[REPEATS] = 0
    F[RET] = 0.0
    F[DISC] = 1.0
    if not done:
        S[DECISIONS] += 1
    return j


@njit(cache=True, inline="always")
def _shrunk(Q, E, act, S, size: int, new_size: int) -> None:
    """After cells were removed (merged or pruned): clear the freed rows and every trace, and count
    the new geometry."""
    Q[new_size:size, :] = 0.0
    E[:size, :] = 0.0
    act[0] = 0
    S[SIZE] = new_size
    S[GEOM] += 1


@njit(cache=True)
def merge_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S) -> int:
    """SPEC §4: merge every mutually nearest pair whose profiles differ by less than rho.

    With ``merge_age > 0`` both cells must have lived ``merge_age`` complete episodes
    after the one that created them. Merged cells take the lower index; later cells
    move down. Returns the number of merges.
    """
    size = S[SIZE]
    if pc[0, 0] != S[GEOM]:  # the geometry changed since the pairs were found
        if IP[MERGE_PAIRS] == 2:  # "nearest"
            found = nearest_pairs_kernel(V, size, inv_scale)
        else:  # "mutual" (0, the paper) or "mutual_ties" (1)
            found = mutual_nearest_pairs_kernel(V, size, inv_scale, IP[MERGE_PAIRS] == 0)
        pc[0, 0] = S[GEOM]
        pc[0, 1] = found.shape[0]
        pc[1 : 1 + found.shape[0], :] = found
    pairs = pc[1 : 1 + pc[0, 1]]
    keep = np.zeros(pairs.shape[0], dtype=np.bool_)
    n_keep = 0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        if not similar_profiles(Q[i], Q[j], P[RHO]):  # SPEC §4, criterion 2
            continue
        if not old_enough(S[EPISODES], born[i, 0], born[j, 0], IP[MERGE_AGE]):
            continue
        if IP[MERGE_SAME_ACTION] and not same_greedy_action(Q[i], Q[j]):
            continue
        keep[k] = True
        n_keep += 1
    if IP[MAKE_ROOM] and S[REFUSED] > 0:
        # Beyond the paper: the budget refused growth this episode; make room by merging as many more
        # pairs, those with the same greedy action and the most similar profiles first.
        extra = min(S[REFUSED], pairs.shape[0] - n_keep)
        for _ in range(extra):
            best = -1
            best_d = np.inf
            for k in range(pairs.shape[0]):
                i, j = pairs[k, 0], pairs[k, 1]
                if keep[k] or not same_greedy_action(Q[i], Q[j]):
                    continue
                d = mean_square_difference(Q[i], Q[j])
                if d < best_d:
                    best, best_d = k, d
            if best < 0:
                break
            keep[best] = True
            n_keep += 1
    if n_keep == 0:
        return 0
    chosen = np.empty((n_keep, 2), dtype=np.int64)
    c = 0
    for k in range(pairs.shape[0]):
        if keep[k]:
            i, j = pairs[k, 0], pairs[k, 1]
            chosen[c, 0] = i
            chosen[c, 1] = j
            c += 1
            merge_profiles(Q[i], Q[j], Q[i])  # SPEC §4
            born[i, 0] = S[EPISODES]
            born[i, 1] = max(born[i, 1], born[j, 1])
            for b in range(2, born.shape[1]):
                born[i, b] += born[j, b]
    mapping = merge_kernel(V, size, chosen)
    compact_rows(Q, mapping)
    compact_rows(born, mapping)
    _shrunk(Q, E, act, S, size, size - n_keep)
    return n_keep


@njit(cache=True)
def prune_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S) -> int:
    """Beyond the paper: remove every cell older than ``prune_after`` episodes in which the agent has
    taken no decision for the last ``prune_after`` episodes (the oldest such cell stays if none
    else would). Later cells move down. Returns the number removed."""
    size = S[SIZE]
    k = IP[PRUNE_AFTER]
    now = S[EPISODES]
    stale = np.zeros(size, dtype=np.bool_)
    n_stale = 0
    for r in range(size):
        if stale_cell(now, born[r, 0], born[r, 1], k):
            stale[r] = True
            n_stale += 1
    if n_stale == size:
        stale[0] = False
        n_stale -= 1
    if n_stale == 0:
        return 0
    w = 0
    for r in range(size):
        if stale[r]:
            continue
        if w != r:
            for d in range(V.shape[1]):
                V[w, d] = V[r, d]
            for b in range(Q.shape[1]):
                Q[w, b] = Q[r, b]
            for b in range(born.shape[1]):
                born[w, b] = born[r, b]
        w += 1
    _shrunk(Q, E, act, S, size, w)
    return n_stale


@njit(cache=True, inline="always")
def _decayed(start: float, decay: float, floor: float, episodes: int) -> float:
    """``max(floor, start * decay ** episodes)``; exactly ``start`` when ``decay`` is 1."""
    if decay == 1.0:
        return start
    return max(floor, start * decay ** episodes)


@njit(cache=True)
def epsilon_at(P, episodes: int) -> float:
    """The exploration rate after ``episodes`` episodes: ``max(epsilon_min, epsilon * decay ** episodes)``."""
    return _decayed(P[EPS0], P[EPS_DECAY], P[EPS_MIN], episodes)


@njit(cache=True)
def alpha_at(P, episodes: int) -> float:
    """The step size after ``episodes`` episodes: ``max(alpha_min, alpha * decay ** episodes)``."""
    return _decayed(P[ALPHA0], P[ALPHA_DECAY], P[ALPHA_MIN], episodes)


@njit(cache=True)
def end_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rec_row) -> None:
    """Count the episode, run the merge pass when due, and fill its record row."""
    S[EPISODES] += 1
    S[IN_EPISODE] = 0
    P[EPS] = epsilon_at(P, S[EPISODES])
    P[ALPHA] = alpha_at(P, S[EPISODES])
    merges = 0
    if IP[MERGE_EVERY] > 0 and S[EPISODES] % IP[MERGE_EVERY] == 0:
        merges = merge_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S)
    if IP[PRUNE_AFTER] > 0:
        prune_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S)
    rec_row[R_STEPS] = S[EP_STEPS]
    rec_row[R_RETURN] = F[EP_RETURN]
    rec_row[R_CELLS] = S[SIZE]
    rec_row[R_APPENDS] = S[APPENDS]
    rec_row[R_MERGES] = merges
    rec_row[R_REFUSED] = S[REFUSED]
    rec_row[R_DECISIONS] = S[DECISIONS]


@njit(cache=True, inline="always")
def decide(src, Q, born, P, j: int, scr) -> int:
    """The ε-greedy decision in cell ``j`` (SPEC §2): on ``Q``, or with count-based exploration on
    the bonus values (into the scratch row ``scr``, shape ``(1, m)``)."""
    if P[BONUS] > 0.0:
        bonus_values(Q, born, P, j, scr)
        return epsilon_greedy(src, scr, 0, P[EPS])
    return epsilon_greedy(src, Q, j, P[EPS])


# -- the generic path: one compiled call per environment step ----------------------------------
#
# The agent's arrays are views of two flat buffers, one float and one int, so that a step hands
# Numba four arrays instead of a dozen (each array argument costs about 60 ns to unbox). The int
# buffer begins with (cap, n, m); :func:`unpack` makes the views, :func:`packed_sizes` says how long
# the buffers are. Float buffer: V (cap, n), Q (cap, m), E (cap, m), inv_scale (n), P, F, a scratch
# observation (n) and a scratch profile (1, m). Int buffer: the dimensions, born (cap, 2 + m),
# act (cap + 1), pc (cap + 1, 2), IP, S.
N_DIMS = 3
#: Statuses of :func:`generic_step` (an action, >= 0, when the episode goes on).
ENDED, NEED_DRAWS, BAD_SHAPE, NEED_ROOM = -1, -3, -4, -5  # (NOT_FINITE is -2)


def _layout(cap: int, n: int, m: int) -> tuple[tuple, tuple]:
    """The shapes of the views, in buffer order: float ``V, Q, E, inv_scale, P, F, x, scr`` and int (after
    the dimensions) ``born, act, pc, IP, S`` (what :func:`unpack` cuts, compiled)."""
    return (((cap, n), (cap, m), (cap, m), (n,), (N_P,), (N_F,), (n,), (1, m)),
            ((cap, 2 + m), (cap + 1,), (cap + 1, 2), (N_IP,), (N_S,)))


def packed_sizes(cap: int, n: int, m: int) -> tuple[int, int]:
    """Lengths of the float and int buffers for ``cap`` cells of ``n`` dimensions and ``m`` actions."""
    f_shapes, i_shapes = _layout(cap, n, m)
    return (sum(math.prod(s) for s in f_shapes), N_DIMS + sum(math.prod(s) for s in i_shapes))


@njit(cache=True, inline="always")
def unpack(fb, ib):
    """The views ``(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr)`` of the packed buffers
    (borrowed, see :func:`avq._numba.borrowed`: they must not outlive the call that made them)."""
    fb, ib = borrowed(fb), borrowed(ib)
    cap, n, m = ib[0], ib[1], ib[2]
    o = 0
    V = fb[o:o + cap * n].reshape((cap, n))
    o += cap * n
    Q = fb[o:o + cap * m].reshape((cap, m))
    o += cap * m
    E = fb[o:o + cap * m].reshape((cap, m))
    o += cap * m
    inv_scale = fb[o:o + n]
    o += n
    P = fb[o:o + N_P]
    o += N_P
    F = fb[o:o + N_F]
    o += N_F
    x = fb[o:o + n]
    o += n
    scr = fb[o:o + m].reshape((1, m))
    k = N_DIMS
    born = ib[k:k + cap * (2 + m)].reshape((cap, 2 + m))
    k += cap * (2 + m)
    act = ib[k:k + cap + 1]
    k += cap + 1
    pc = ib[k:k + 2 * (cap + 1)].reshape((cap + 1, 2))
    k += 2 * (cap + 1)
    IP = ib[k:k + N_IP]
    k += N_IP
    S = ib[k:k + N_S]
    return V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr


def python_views(fb: np.ndarray, ib: np.ndarray) -> tuple:
    """The same views as :func:`unpack`, made by NumPy (the agent's attributes)."""
    f_shapes, i_shapes = _layout(*(int(v) for v in ib[:N_DIMS]))
    f_views, i_views = _cut(fb, 0, f_shapes), _cut(ib, N_DIMS, i_shapes)
    V, Q, E, inv_scale, P, F, x, scr = f_views
    born, act, pc, IP, S = i_views
    return V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr


def _cut(buf: np.ndarray, start: int, shapes: tuple) -> list[np.ndarray]:
    """Consecutive views of ``buf`` from ``start``, one per shape."""
    out, o = [], start
    for shape in shapes:
        size = math.prod(shape)
        out.append(buf[o:o + size].reshape(shape))
        o += size
    return out


@njit(cache=True)
def generic_start(fb, ib, raw, cursor, obs) -> int:
    """Start an episode at ``obs`` (SPEC §3's first vector if the codebook is empty) and decide its
    first action; or ``NEED_ROOM`` / ``NEED_DRAWS`` / ``BAD_SHAPE`` / ``NOT_FINITE``, changing nothing."""
    raw, cursor = borrowed(raw), borrowed(cursor)
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr = unpack(fb, ib)
    if obs.shape[0] != x.shape[0]:
        return BAD_SHAPE
    if S[SIZE] + 1 > V.shape[0]:
        return NEED_ROOM
    if raw.shape[0] - cursor[0] < DRAWS_PER_DECISION:  # (a step takes at most one decision)
        return NEED_DRAWS
    for d in range(x.shape[0]):
        x[d] = obs[d]
        if not math.isfinite(x[d]):
            return NOT_FINITE
    cell = begin_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x)
    S[ACTION] = decide((raw, cursor), Q, born, P, cell, scr)
    return S[ACTION]


@njit(cache=True)
def generic_step(fb, ib, raw, cursor, obs, r, collision, terminated, truncated) -> int:
    """One environment step of the generic path: :func:`observe`, then at the end of an aggregate
    transition the next decision and :func:`learn`. Returns the action to take next, ``ENDED``, or
    (changing nothing) ``NEED_ROOM``, ``NEED_DRAWS``, ``BAD_SHAPE``, ``NOT_FINITE``."""
    raw, cursor = borrowed(raw), borrowed(cursor)
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr = unpack(fb, ib)
    if obs.shape[0] != x.shape[0]:
        return BAD_SHAPE
    if S[SIZE] + 3 > V.shape[0]:  # a step appends at most three cells
        return NEED_ROOM
    if raw.shape[0] - cursor[0] < DRAWS_PER_DECISION:  # (a step takes at most one decision)
        return NEED_DRAWS
    for d in range(x.shape[0]):
        x[d] = obs[d]
    done = terminated or truncated
    j = observe(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, float(r), collision, done)
    if j == NOT_FINITE:
        return NOT_FINITE
    if j < 0:
        return S[ACTION]
    a_next = S[ACTION]
    if not terminated:
        a_next = decide((raw, cursor), Q, born, P, j, scr)
    learn(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, j, a_next, terminated, done)
    return ENDED if done else a_next
