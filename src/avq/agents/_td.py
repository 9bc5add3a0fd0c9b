"""The learning rule as small compiled functions on arrays (docs/explanation/paper.md#acting, #learning): one copy, called by every agent
and every path (the fused loops, and the generic path's one compiled call per step).

Names follow the time-indexed convention: ``q_tm1`` is the value of the decision
being updated, ``r_t`` the return of the transition that followed it, ``q_t`` the
value of the next decision. Random draws come from a source ``src`` of
:mod:`avq._random`: the agent's ``Generator`` inside a fused loop, or its
:class:`~avq._random.RawStream` elsewhere; both give the same numbers.

The rows whose traces may be non-zero are kept in an *active list* ``act``
(``act[0]`` of them in ``act[1:]``), so that an update touches only those: the
others would change by ``0 * step``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from avq._random import below, uniform

__all__ = [
    "greedy_ties",
    "nth_tie",
    "epsilon_greedy",
    "decide",
    "sarsa_td_error",
    "mark_active",
    "clear_traces",
    "trace_update",
    "sarsa_lambda",
    "table_step",
    "tile_step",
    "SarsaParams",
]


@njit(cache=True, inline="always")
def greedy_ties(values: np.ndarray, row: int) -> tuple[int, int]:
    """The first best action of ``values[row]`` and how many actions share that value."""
    m = values.shape[1]
    best = values[row, 0]
    for k in range(1, m):
        if values[row, k] > best:
            best = values[row, k]
    first = -1
    n_ties = 0
    for k in range(m):
        if values[row, k] == best:
            if n_ties == 0:
                first = k
            n_ties += 1
    return first, n_ties


@njit(cache=True, inline="always")
def nth_tie(values: np.ndarray, row: int, pick: int) -> int:
    """The ``pick``-th (from 0, in index order) of the actions sharing ``values[row]``'s maximum."""
    first, _ = greedy_ties(values, row)
    best = values[row, first]
    for k in range(values.shape[1]):
        if values[row, k] == best:
            if pick == 0:
                return k
            pick -= 1
    return first


@njit(cache=True, inline="always")
def epsilon_greedy(src, values: np.ndarray, row: int, epsilon: float) -> int:
    """ε-greedy over the profile ``values[row]``, ties broken uniformly at random (docs/explanation/paper.md#acting).

    Draws one uniform number; if it is below ``epsilon`` a uniformly random action
    is taken (one more draw), otherwise the greedy action, with one more draw only
    when several actions share the maximum.
    """
    if uniform(src) < epsilon:
        return below(src, values.shape[1])
    a, n_ties = greedy_ties(values, row)
    if n_ties == 1:
        return a
    return nth_tie(values, row, below(src, n_ties))


@njit(cache=True, inline="always")
def sarsa_td_error(q_tm1: float, r_t: float, discount_t: float, q_t: float, terminal: bool) -> float:
    """TD error of one (aggregate) transition (docs/explanation/paper.md#learning).

    ``discount_t`` is ``gamma ** k`` for a transition of ``k`` primitive steps and
    ``r_t`` its discounted return. A terminal transition does not bootstrap; a
    truncated one does.
    """
    if terminal:
        return r_t - q_tm1
    return r_t + discount_t * q_t - q_tm1


@njit(cache=True, inline="always")
def mark_active(act: np.ndarray, s: int) -> None:
    """Add row ``s`` to the active list ``act`` unless it is there."""
    n = act[0]
    for k in range(1, n + 1):
        if act[k] == s:
            return
    act[n + 1] = s
    act[0] = n + 1


@njit(cache=True, inline="always")
def clear_traces(E: np.ndarray, act: np.ndarray) -> None:
    """Zero the traces of the active rows and empty the list (the start of an episode)."""
    for k in range(1, act[0] + 1):
        for b in range(E.shape[1]):
            E[act[k], b] = 0.0
    act[0] = 0


@njit(cache=True, inline="always")
def trace_update(
    Q, E, rows, n_rows: int, s_tm1: int, a_tm1: int, delta: float, alpha: float, trace_decay: float, replacing: bool
) -> None:
    """The Sarsa(λ) update in place (docs/explanation/paper.md#learning) of the values ``Q`` and traces ``E``
    (``(rows, actions)`` arrays), over ``rows[:n_rows]`` (every row whose trace may be non-zero).

    ``E[s, a] = 1`` (replacing) or ``+= 1`` (accumulating); ``Q += alpha * delta * E``;
    ``E *= trace_decay``, where ``trace_decay = gamma ** k * lambda``.
    The product ``alpha * delta`` is formed first.
    """
    if replacing:
        E[s_tm1, a_tm1] = 1.0
    else:
        E[s_tm1, a_tm1] += 1.0
    step = alpha * delta
    for k in range(n_rows):
        s = rows[k]
        for b in range(Q.shape[1]):
            Q[s, b] += step * E[s, b]
            E[s, b] *= trace_decay


@njit(cache=True, inline="always")
def sarsa_lambda(
    Q, E, act, s_tm1: int, a_tm1: int, delta: float, alpha: float, trace_decay: float, replacing: bool
) -> None:
    """:func:`trace_update` over the active list ``act``, with ``s_tm1`` added to it."""
    mark_active(act, s_tm1)
    trace_update(Q, E, act[1:], act[0], s_tm1, a_tm1, delta, alpha, trace_decay, replacing)


class SarsaParams(NamedTuple):
    """The parameters of tabular Sarsa(λ)'s step (:func:`table_step`)."""

    epsilon: float
    alpha: float
    gamma: float
    lam: float
    replacing: bool


@njit(cache=True, inline="always")
def table_step(src, Q, E, act, s, a, r, s2, terminated, sp: SarsaParams) -> int:
    """One step of tabular Sarsa(λ) (one decision per step) from row ``s``, action ``a``, to row ``s2``
    with reward ``r``: the next action (``a`` itself on a terminal step, which draws nothing), then
    the update of ``(s, a)``. The one step of ``tabular`` and ``grid``, on both paths. (From Python, ``sp``
    may be a plain tuple in the same order: the dispatcher types a tuple faster than a named one.)"""
    epsilon, alpha, gamma, lam, replacing = sp
    if terminated:
        a2 = a
        delta = sarsa_td_error(Q[s, a], r, gamma, 0.0, True)
    else:
        a2 = epsilon_greedy(src, Q, s2, epsilon)
        delta = sarsa_td_error(Q[s, a], r, gamma, Q[s2, a2], False)
    sarsa_lambda(Q, E, act, s, a, delta, alpha, gamma * lam, replacing)
    return a2


@njit(cache=True)
def decide(src, values: np.ndarray, row: int, epsilon: float) -> int:
    """:func:`epsilon_greedy` as a function of its own, for callers in Python."""
    return epsilon_greedy(src, values, row, epsilon)


@njit(cache=True)
def tile_step(w, e, rows, n_rows, s_tm1, a, delta, alpha, trace_decay, replacing) -> None:
    """:func:`trace_update` for the tile-coded agents, called from Python (their traces are marked by
    ``avq.agents.tiles.mark_traces``; ``rows[:n_rows]`` are the tiles in use)."""
    trace_update(w, e, rows, n_rows, s_tm1, a, delta, alpha, trace_decay, replacing)
