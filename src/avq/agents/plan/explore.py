"""``avq-plan``'s decisions: ε-greedy on the planned values, and (``known_radius``) optimism for a decision never
tried from near here; and which cells' values owe nothing to optimism (:func:`owes_no_optimism`).

A cell's pair ``(c, a)`` is known once it has been tried (``known_after``), wherever in the cell that was. In a
large cell, and above all in one that straddles a wall, a decision's outcome depends on where in the cell it
starts: a decision tried only from the cell's far side may be worth nothing there and everything here, and the
greedy agent never tries it here again. With ``known_radius``, a decision whose transitions all started farther
than that (scaled distance, between the current observation and the mean start of each successor's transitions)
is taken as worth at least ``v_opt`` for this one decision: the agent tries it here once, and the outcome split
(:mod:`avq.agents.plan.kernels`) then cuts the cell if the outcomes disagree. The planned values themselves do not
change, so the greedy policy (exploration off) is the model's.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from avq.agents._td import epsilon_greedy
from avq.agents.plan.model import ModelArrays, ModelParam, known, settled
from avq.agents.plan.state import PlanArrays, PlanParam

__all__ = ["decide", "owes_no_optimism", "tried_near"]


@njit(cache=True, inline="always")
def tried_near(ag: PlanArrays, m: ModelArrays, c: int, a: int, x, radius: float) -> bool:
    """Whether some successor of ``(c, a)`` was reached by transitions whose mean start lies within ``radius``
    (scaled) of ``x``."""
    e_xs, inv_scale = ag.e_xs, ag.inv_scale
    e = m.head[c, a]
    while e >= 0:
        k = m.e_n[e]
        if k > 0:
            s = 0.0
            for d in range(x.shape[0]):
                z = (e_xs[e, d] / k - x[d]) * inv_scale[d]
                s += z * z
            if s <= radius * radius:
                return True
        e = m.e_next[e]
    return False


@njit(cache=True)
def decide(ag: PlanArrays, m: ModelArrays, src, c: int, x) -> int:
    """The action to take in cell ``c`` at observation ``x``: ε-greedy on ``Q[c]``, each decision never tried
    from within ``known_radius`` of ``x`` worth at least ``v_opt`` (``known_radius`` off: ``Q[c]`` itself)."""
    radius, epsilon = ag.P[PlanParam.KNOWN_RADIUS], ag.P[PlanParam.EPSILON]
    if radius < 0.0:
        return epsilon_greedy(src, m.Q, c, epsilon)
    row = np.empty((1, m.Q.shape[1]))
    v_opt = m.MP[ModelParam.V_OPT]
    for a in range(m.Q.shape[1]):
        q = m.Q[c, a]
        row[0, a] = q if q >= v_opt or tried_near(ag, m, c, a, x, radius) else v_opt
    return epsilon_greedy(src, row, 0, epsilon)


@njit(cache=True, inline="always")
def owes_no_optimism(m: ModelArrays, s: int) -> bool:
    """``V(s)`` owes nothing directly to optimism: ``s`` is :func:`~avq.agents.plan.model.settled`, or a decision
    it knows is worth more than an untried one (``v_opt``), so that the explorer never tries the others there
    (ε aside; on a tie it may) and trying them could not raise its value. Near a goal worth more than ``v_opt`` a
    cell may never settle: no untried decision there is worth trying."""
    if settled(m, s):
        return True
    best = -np.inf  # (the best known decision's value)
    for a in range(m.cnt.shape[1]):
        if known(m, s, a):
            best = max(best, m.Q[s, a])
    return best > m.MP[ModelParam.V_OPT]
