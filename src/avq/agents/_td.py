"""The learning rule as small pure functions on arrays (SPEC §2, §5).

Names follow the time-indexed convention: ``q_tm1`` is the value of the decision
being updated, ``r_t`` the return of the transition that followed it, ``q_t`` the
value of the next decision. Every function works on preallocated NumPy arrays and
scalars only, so the same code can be compiled later.
"""

from __future__ import annotations

import numpy as np

__all__ = ["epsilon_greedy", "sarsa_td_error", "sarsa_lambda_update"]


def epsilon_greedy(q_row: np.ndarray, epsilon: float, rng: np.random.Generator) -> int:
    """ε-greedy over one action-value profile, ties broken uniformly at random (SPEC §2).

    Draws one uniform number; if it is below ``epsilon`` a uniformly random action
    is taken (one more draw), otherwise the greedy action, with one more draw only
    when several actions share the maximum.
    """
    if rng.random() < epsilon:
        return int(rng.integers(q_row.shape[0]))
    row = q_row.tolist()  # plain floats: much faster than NumPy scalars for a handful of actions
    best = max(row)
    if row.count(best) == 1:
        return row.index(best)
    ties = [k for k, v in enumerate(row) if v == best]
    return ties[int(rng.integers(len(ties)))]


def sarsa_td_error(q_tm1: float, r_t: float, discount_t: float, q_t: float, terminal: bool) -> float:
    """TD error of one (aggregate) transition (SPEC §5).

    ``discount_t`` is ``gamma ** k`` for a transition of ``k`` primitive steps and
    ``r_t`` its discounted return. A terminal transition does not bootstrap; a
    truncated one does.
    """
    if terminal:
        return r_t - q_tm1
    return r_t + discount_t * q_t - q_tm1


def sarsa_lambda_update(
    q: np.ndarray,
    e: np.ndarray,
    s_tm1: int,
    a_tm1: int,
    delta: float,
    alpha: float,
    trace_decay: float,
    replacing: bool,
    n_rows: int,
) -> None:
    """Sarsa(λ) update in place over the first ``n_rows`` rows (SPEC §5).

    ``E[s, a] = 1`` (replacing) or ``+= 1`` (accumulating); ``Q += alpha * delta * E``;
    ``E *= trace_decay`` where ``trace_decay = gamma ** k * lambda``.
    The product ``alpha * delta`` is formed first, so every implementation
    computes exactly the same floating-point numbers.
    """
    if replacing:
        e[s_tm1, a_tm1] = 1.0
    else:
        e[s_tm1, a_tm1] += 1.0
    step = alpha * delta
    qv = q[:n_rows]
    ev = e[:n_rows]
    qv += step * ev
    ev *= trace_decay
