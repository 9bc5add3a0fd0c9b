"""AVQ Sarsa(λ) as compiled kernels on packed arrays (docs/explanation/paper.md: Acting to Learning).

One implementation of the agent's rules serves both paths:

* the generic path (any Gymnasium environment, :mod:`avq.agents.avq_sarsa.generic`) steps the
  environment in Python and makes one compiled call per step (:func:`observe`, then at the end of
  an aggregate transition :func:`decide` and :func:`learn`);
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
the episode in ``S`` (int) and ``F`` (float). The kernels take the arrays they write one by one and
what they only read as records: :class:`Params` (``P``, ``IP``, ``inv_scale``) and the step, :class:`Step`
(under Numba 0.68 an inlined kernel that writes through a record argument can lose those writes). The parameters' indices are the members of
:class:`FloatParam` and :class:`IntParam`, the state's the module constants below. The end of an
episode (merging, pruning, decay) is in :mod:`avq.agents.avq_sarsa.episode_end`. Skipping rows whose traces are zero and reusing the pairs change
no result: those rows would be updated by ``0 * step``.
"""

from __future__ import annotations

import math
from enum import auto
from typing import NamedTuple

import numpy as np
from numba import njit

from avq._numba import row
from avq.agents._params import ParamIndex
from avq.agents._td import clear_traces, epsilon_greedy, sarsa_lambda, sarsa_td_error
from avq.quantizer import append_vector, nearest_index, scaled_distance
from avq.rules import (
    APPEND as APPEND_OUTCOME,
    CHI as CHI_OUTCOME,
    closes_cycle,
    collision_rule,
    collision_split,
    decision_goes_on,
    may_append,
    repeat_limit_reached,
    reward_jump,
    value_jump,
)


# The parameters, declared once (avq.agents._params): a member's value is its index in P (floats) or IP
# (ints), its name in lower case the agent parameter that fills it (pack_params, in AVQSarsa._setup).
class FloatParam(ParamIndex):
    """``P``: the float parameters (``ALPHA_NOW`` and ``EPSILON_NOW``: the step size and exploration rate
    after their decay, :func:`~avq.agents.avq_sarsa.episode_end.alpha_at` and ``epsilon_at``)."""

    ALPHA_NOW = auto()
    LAM = auto()
    GAMMA = auto()
    EPSILON_NOW = auto()
    D_MIN = auto()
    RHO = auto()
    CHI = auto()
    Q_INIT = auto()
    VALUE_TRIGGER = auto()  # (None: -1)
    REWARD_TRIGGER = auto()  # (None: -1)
    EPSILON = auto()
    EPSILON_DECAY = auto()
    EPSILON_MIN = auto()
    ADAPT_RATE = auto()
    ALPHA = auto()
    ALPHA_DECAY = auto()
    ALPHA_MIN = auto()
    EXPLORE_BONUS = auto()


class IntParam(ParamIndex):
    """``IP``: the integer parameters (booleans as 0 and 1)."""

    TRACES = auto()  # (1: replacing, 0: accumulating)
    MERGE_EVERY = auto()
    MERGE_AGE = auto()
    MAX_CELLS = auto()
    MERGE_SAME_ACTION = auto()
    COLLISION_SPLIT = auto()
    MERGE_PAIRS = auto()  # (the index of its value in MERGE_PAIRS)
    CYCLE_SPLIT = auto()
    PRUNE_AFTER = auto()
    MAKE_ROOM = auto()
    MAX_REPEAT = auto()  # (None: 0)


class Cells(NamedTuple):
    """The agent's arrays in one record, as the fused loop takes them (the kernels take them one by one)."""

    V: np.ndarray
    Q: np.ndarray
    E: np.ndarray
    born: np.ndarray
    act: np.ndarray
    pc: np.ndarray
    inv_scale: np.ndarray
    P: np.ndarray
    IP: np.ndarray
    S: np.ndarray
    F: np.ndarray


class Params(NamedTuple):
    """What the step's kernels only read of the agent's arrays: the parameters and the metric (one argument
    instead of three; the arrays they write they take one by one)."""

    P: np.ndarray
    IP: np.ndarray
    inv_scale: np.ndarray


class Step(NamedTuple):
    """One primitive step as the kernels read it: it reached observation ``x`` with reward ``r``; whether it
    hit a wall, whether the episode ended at a terminal state (``terminated``) or at all (``done``)."""

    x: np.ndarray
    r: float
    collision: bool
    terminated: bool
    done: bool


#: The lengths of P and IP.
N_P, N_IP = len(FloatParam), len(IntParam)
#: The merge pass's pair rules (``merge_pairs``), in the order of their code in the kernels.
MERGE_PAIRS = ("mutual", "mutual_ties", "nearest")

# S: int state
SIZE, CELL, ACTION, EP_STEPS, APPENDS, REFUSED, DECISIONS, EPISODES, IN_EPISODE, GEOM = range(10)
PREV_CELL, PREV_GREEDY = 10, 11  # the cell of the decision before the current one, and whether it was greedy
REPEATS = 12  # the primitive steps taken so far with the current decision
N_S = 13
# F: float state
RET, DISC, EP_RETURN, PREV_R = range(4)
N_F = 4
#: What an episode's start sets (:func:`begin_episode_in`), as ``(index, value)`` pairs: in S the episode's
#: counters, then the decision before the first (none) and the current one's steps; in F the transition's
#: return and discount, the episode's return and the last reward.
S_AT_START: tuple[tuple[int, int], ...] = ((EP_STEPS, 0), (APPENDS, 0), (REFUSED, 0), (DECISIONS, 1), (IN_EPISODE, 1))
S_AT_START += ((PREV_CELL, -1), (PREV_GREEDY, 0), (REPEATS, 0))
F_AT_START = ((RET, 0.0), (DISC, 1.0), (EP_RETURN, 0.0), (PREV_R, 0.0))
# Returned by observe() for an observation or reward that is NaN or infinite.
NOT_FINITE = -2


@njit(cache=True, inline="always")
def _may_append(dist_nearest: float, P, IP, S) -> bool:
    """The paper (docs/explanation/paper.md#growing): never within d_min of an existing vector; never beyond max_cells (counted)."""
    if not may_append(dist_nearest, P[FloatParam.D_MIN]):
        return False
    if S[SIZE] >= IP[IntParam.MAX_CELLS]:
        S[REFUSED] += 1
        return False
    return True


@njit(cache=True, inline="always")
def _append(V, Q, E, born, S, x, parent: int) -> int:
    """Append ``x`` as a cell whose profile is a copy of ``parent``'s (docs/explanation/paper.md#growing)."""
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
        out[0, b] = Q[j, b] + P[FloatParam.EXPLORE_BONUS] / np.sqrt(1.0 + born[j, 2 + b])


@njit(cache=True, inline="always")
def first_vector(V, Q, E, born, S, P, x) -> None:
    """The paper (docs/explanation/paper.md#growing): the codebook starts with the very first observation
    ``x`` (nothing happens once it has a vector)."""
    if S[SIZE] == 0:
        for d in range(x.shape[0]):
            V[0, d] = x[d]
        for b in range(Q.shape[1]):
            Q[0, b] = P[FloatParam.Q_INIT]
            E[0, b] = 0.0
        born[0, 0] = 0
        born[0, 1] = 0
        S[SIZE] = 1
        S[GEOM] += 1


@njit(cache=True, inline="always")
def begin_episode_in(E, born, act, S, F, cell: int) -> int:
    """Start an episode in ``cell``, the nearest cell of its first observation; return it. The caller then
    picks the action."""
    clear_traces(E, act)
    for k, v in S_AT_START:
        S[k] = v
    for k, f in F_AT_START:
        F[k] = f
    S[CELL] = cell
    born[cell, 1] = S[EPISODES] + 1
    return cell


@njit(cache=True, inline="always")
def begin_episode(V, Q, E, born, act, S, F, par: Params, x) -> int:
    """Start an episode at observation ``x``; return its cell. The caller then picks the action."""
    first_vector(V, Q, E, born, S, par.P, x)
    cell, _ = nearest_index(V, S[SIZE], x, par.inv_scale)
    return begin_episode_in(E, born, act, S, F, cell)


@njit(cache=True)
def observe(V, Q, E, born, S, F, par: Params, st: Step) -> int:
    """Account for one primitive step ``st`` (that reached ``st.x`` with reward ``st.r``).

    Returns -1 while the aggregate transition goes on (same cell, no collision, not
    ``done``, fewer than ``max_repeat`` steps), else the cell ``j`` it ends in, after
    the growth rules of the paper (docs/explanation/paper.md#growing) that act at once (collision; reward jump). Returns ``NOT_FINITE``, changing
    nothing, when ``x`` or ``r`` is NaN or infinite.
    """
    x = st.x
    if not math.isfinite(st.r):
        return NOT_FINITE
    for d in range(x.shape[0]):
        if not math.isfinite(x[d]):
            return NOT_FINITE
    j, d2 = nearest_index(V, S[SIZE], x, par.inv_scale)
    return observe_at(V, Q, E, born, S, F, par, st, j, d2)


@njit(cache=True, inline="always")
def observe_at(V, Q, E, born, S, F, par: Params, st: Step, j: int, d2_j: float) -> int:
    """:func:`observe` with the nearest vector ``j`` of ``st.x`` and its squared distance already known (the
    distance itself is taken only where a rule reads it, on a collision or a reward jump)."""
    P, IP, inv_scale = par
    x, r, collision, _, done = st
    i = S[CELL]
    a = S[ACTION]
    S[EP_STEPS] += 1
    S[REPEATS] += 1
    F[RET] += F[DISC] * r
    F[DISC] *= P[FloatParam.GAMMA]
    F[EP_RETURN] += r
    if P[FloatParam.REWARD_TRIGGER] > 0.0:
        jump = reward_jump(r, F[PREV_R], S[EP_STEPS], P[FloatParam.REWARD_TRIGGER])
        F[PREV_R] = r
        if jump and not collision and _may_append(np.sqrt(d2_j), P, IP, S):
            j = _append(V, Q, E, born, S, x, i)
    if P[FloatParam.ADAPT_RATE] > 0.0 and not collision:
        # Beyond the paper: move the vector of x's cell toward x (online k-means, rate adapt_rate).
        for d in range(x.shape[0]):
            V[j, d] += P[FloatParam.ADAPT_RATE] * (x[d] - V[j, d])
        S[GEOM] += 1
    # The paper (docs/explanation/paper.md#acting): the decision goes on while the cell stays the same; beyond the paper, for at most max_repeat
    # steps, after which it ends in that same cell and learn() takes it as any other aggregate transition.
    if decision_goes_on(j == i, collision, done) and not repeat_limit_reached(S[REPEATS], IP[IntParam.MAX_REPEAT]):
        return -1
    if collision:
        # The paper (docs/explanation/paper.md#growing), collision rule (avq.rules.collision_rule).
        dist_j = np.sqrt(d2_j)
        dist_i = dist_j if j == i else scaled_distance(V, i, x, inv_scale)
        outcome = collision_rule(dist_i, dist_j, P[FloatParam.D_MIN])
        if (
            outcome == CHI_OUTCOME
            and IP[IntParam.COLLISION_SPLIT]
            and S[SIZE] < IP[IntParam.MAX_CELLS]
            and collision_split(dist_i, np.argmax(row(Q, i)) == a, Q[i, a], P[FloatParam.CHI])
        ):
            # Beyond the paper: the cell's greedy action hit a wall here but is still the best one
            # elsewhere in the cell; instead of condemning it for the whole cell, split x off.
            j = _append(V, Q, E, born, S, x, i)
            Q[j, a] = P[FloatParam.CHI]
        elif outcome == CHI_OUTCOME:
            Q[i, a] = P[FloatParam.CHI]
        elif outcome == APPEND_OUTCOME and _may_append(dist_j, P, IP, S):
            j = _append(V, Q, E, born, S, x, i)
            Q[j, a] = P[FloatParam.CHI]  # the rule at the new cell itself: ||y_c - x|| = 0 <= d_min
    return j


@njit(cache=True, inline="always")
def learn(V, Q, E, born, act, S, F, par: Params, st: Step, j: int, a_next: int) -> int:
    """The paper (docs/explanation/paper.md#learning): the Sarsa(λ) update of the transition ``(S[CELL], S[ACTION]) -> (j, a_next)``.

    Then the optional value-change trigger (docs/explanation/paper.md#growing). Moves the agent to the next
    decision and returns its cell.
    """
    P, IP, inv_scale = par
    x, terminated, done = st.x, st.terminated, st.done
    i = S[CELL]
    a = S[ACTION]
    born[i, 2 + a] += 1  # one more decision (i, a)
    greedy = True  # was the decision (i, a) greedy? (a best action of Q[i], ties included; cycle split only)
    if IP[IntParam.CYCLE_SPLIT]:
        for b in range(Q.shape[1]):
            if Q[i, b] > Q[i, a]:
                greedy = False
                break
    if terminated:
        delta = sarsa_td_error(Q[i, a], F[RET], F[DISC], 0.0, True)
    else:
        delta = sarsa_td_error(Q[i, a], F[RET], F[DISC], Q[j, a_next], False)
    sarsa_lambda(Q, E, act, i, a, delta, P[FloatParam.ALPHA_NOW], F[DISC] * P[FloatParam.LAM], IP[IntParam.TRACES] != 0)
    appended = False
    if value_jump(delta, P[FloatParam.VALUE_TRIGGER]):
        if _may_append(scaled_distance(V, j, x, inv_scale), P, IP, S):
            j = _append(V, Q, E, born, S, x, j)
            appended = True
    if (
        IP[IntParam.CYCLE_SPLIT]
        and not (done or appended)
        and greedy
        and S[PREV_GREEDY]
        and closes_cycle(S[PREV_CELL], i, j)
    ):
        # Beyond the paper: two greedy decisions led from cell j to i and back into j, a cycle
        # that the greedy policy would repeat forever: the cell j is wrong for part of it.
        # Split off the square of the return (x, unless it is j's own vector).
        if scaled_distance(V, j, x, inv_scale) > 0.0:
            if S[SIZE] < IP[IntParam.MAX_CELLS]:
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
def decide(src, Q, born, P, j: int, scr) -> int:
    """The ε-greedy decision in cell ``j`` (docs/explanation/paper.md#acting): on ``Q``, or with count-based exploration on
    the bonus values (into the scratch row ``scr``, shape ``(1, m)``)."""
    if P[FloatParam.EXPLORE_BONUS] > 0.0:
        bonus_values(Q, born, P, j, scr)
        return epsilon_greedy(src, scr, 0, P[FloatParam.EPSILON_NOW])
    return epsilon_greedy(src, Q, j, P[FloatParam.EPSILON_NOW])
