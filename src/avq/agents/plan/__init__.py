"""The model-based agents: a learned model planned over by prioritized sweeping.

- ``model.py``: the model of (state, action) -> successor and prioritized sweeping over it;
- ``agent.py``: :class:`PlanningAVQ` (``avq``, ``avq-plan``), AVQ's cells as the model's states;
- ``kernels.py``: its rules (growth, splits, remembered transitions) as compiled kernels;
- ``sweeping.py``: :class:`PrioritizedSweeping` (``tabular-ps``, ``grid-ps``), the baseline on
  distinct observations or a fixed grid;
- ``fused.py``: both agents' compiled training loops on the built-in mazes.
"""

from avq.agents.plan.agent import PlanningAVQ
from avq.agents.plan.sweeping import PrioritizedSweeping

__all__ = ["PlanningAVQ", "PrioritizedSweeping"]
