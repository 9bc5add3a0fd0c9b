"""``tabular-ps``'s step: a state per observation, one environment step a transition of the model
(:mod:`avq.agents.plan.model`). Both paths call it: ``PrioritizedSweeping`` stepping the environment, and
the fused loop on a GridMaze (:func:`avq.agents.plan.fused.run_ps_grid_maze`)."""

from __future__ import annotations

from numba import njit

from avq.agents._td import epsilon_greedy
from avq.agents.plan.model import ModelArrays, record, settle

__all__ = ["observe", "ps_step"]


@njit(cache=True, inline="always")
def observe(m: ModelArrays, s: int, a: int, r: float, disc: float, s2: int, budget: int) -> int:
    """Record the transition ``(s, a) -> s2`` (return ``r``, discount ``disc``; ``s2 = -1`` terminal), then
    :func:`~avq.agents.plan.model.settle` ``s``. Returns the backups done."""
    record(m, s, a, r, disc, s2, 1)
    return settle(m, s, budget)


@njit(cache=True, inline="always")
def ps_step(
    m: ModelArrays, src, s: int, a: int, r: float, gamma: float, s2: int, terminated: bool, epsilon: float, budget: int
) -> int:
    """One step of ``tabular-ps``: record ``(s, a) -> s2`` with reward ``r`` and discount ``gamma`` (terminal: no
    successor), plan (:func:`observe`), then the next action in ``s2``, ε-greedy (``a`` itself on a terminal
    step, which draws nothing)."""
    observe(m, s, a, r, gamma, -1 if terminated else s2, budget)
    if terminated:
        return a
    return epsilon_greedy(src, m.Q, s2, epsilon)
