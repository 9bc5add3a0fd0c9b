"""The model-based agents: a learned model planned over by prioritized sweeping.

- ``model.py``: the model of (state, action) -> successor and prioritized sweeping over it (``queue.py``:
  the planner's queue);
- ``agent.py``: :class:`PlanningAVQ` (``avq``, ``avq-plan``), AVQ's cells as the model's states;
- ``state.py``: its arrays as its kernels take them (a record), its parameters and state indices;
- ``kernels.py``: its rules (the step, growth, splits) as compiled kernels; ``memory.py``: the remembered
  transitions the model follows when the cells change;
- ``sweeping.py``: :class:`PrioritizedSweeping` (``tabular-ps``, ``grid-ps``), the baseline on
  distinct observations or a fixed grid, and what both agents show of their model (``ModelPlanner``);
- ``fused.py``: both agents' compiled training loops on the built-in mazes.
"""

from avq.agents.plan.agent import PlanningAVQ
from avq.agents.plan.sweeping import PrioritizedSweeping

__all__ = ["PlanningAVQ", "PrioritizedSweeping"]
