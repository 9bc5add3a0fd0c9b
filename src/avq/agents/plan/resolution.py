"""The floor of the cells that decisions grow, finer as the data catch up with the cells (``finer_when_settled``).

``d_min`` bounds every growth of ``avq-plan``'s codebook. The growth from decisions, a decision that stays
``split_after`` steps in its cell and the outcome split, uses a floor that starts at ``d_min`` and halves, at most
``finer_when_settled`` times, each at the end of an episode at which at least :data:`FINER_SHARE` of the cells (and
at least :data:`~avq.agents._value_weights.MIN_CELLS`) have every decision known: where the model has tried nearly
everything its cells allow, finer cells can be learned. The paper's growth on collisions keeps ``d_min``. The number
of halvings so far is the agent's state ``S[FINER]`` (saved with it); the floor is ``d_min * 0.5 ** S[FINER]``
(:func:`decision_floor`, which the kernels ask). Docs: docs/results/dimensions.md#finer-when-settled.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from avq.agents._value_weights import MIN_CELLS
from avq.agents.plan.model import ModelArrays, settled
from avq.agents.plan.state import FINER, SIZE, PlanArrays, PlanParam

__all__ = ["FINER_SHARE", "decision_floor", "refine_when_settled", "settled_cells"]

#: The share of the cells with every decision known at which the floor halves.
FINER_SHARE = 0.9


@njit(cache=True)
def settled_cells(m: ModelArrays, size: int, out) -> None:  # pragma: no cover  (compiled)
    """``out[s]``, for each cell ``s`` below ``size``: whether every decision of ``s`` is known
    (:func:`avq.agents.plan.model.settled`): what this rule and ``reweight_when_full`` count."""
    for s in range(size):
        out[s] = settled(m, s)


@njit(cache=True, inline="always")
def decision_floor(P: np.ndarray, S: np.ndarray) -> float:
    """The floor of the growth from decisions: ``d_min`` halved ``S[FINER]`` times."""
    return P[PlanParam.D_MIN] * 0.5 ** S[FINER]


@njit(cache=True)
def refine_when_settled(ag: PlanArrays, m: ModelArrays, limit: int) -> bool:
    """At an episode's end (:func:`avq.agents.plan.kernels.end_transition`, in both loops): halve the floor
    (``S[FINER] += 1``) if it has halved fewer than ``limit`` times and at least :data:`FINER_SHARE` of the cells,
    and :data:`MIN_CELLS`, are settled. Whether it did."""
    n = ag.S[SIZE]
    if ag.S[FINER] >= limit or n < MIN_CELLS:
        return False
    out = np.zeros(n, dtype=np.bool_)
    settled_cells(m, n, out)
    if out.sum() < FINER_SHARE * n:
        return False
    ag.S[FINER] += 1
    return True
