"""avq's agents and the registry of agent names.

The agents by name, with their rules and defaults: `avq.agents.registry`. The model file that
`avq.agents.BaseAgent.save` writes: `avq.agents.save_util`.
"""

from avq._validate import InvalidParameterError
from avq.agents import registry, save_util  # noqa: F401  (public: the names and defaults, the model file)
from avq.agents.actions.agent import ActionCodebookSarsa
from avq.agents.avq_sarsa.agent import AVQSarsa
from avq.agents.base import BaseAgent, NotFiniteError, load
from avq.agents.baselines.grid import GridSarsa
from avq.agents.baselines.tabular import TabularSarsa
from avq.agents.baselines.tiles import TileSarsa
from avq.agents.callbacks import BaseCallback, CallbackList, CheckpointCallback, EvalCallback, ProgressBarCallback
from avq.agents.plan.agent import PlanningAVQ
from avq.agents.plan.sweeping import PrioritizedSweeping
from avq.agents.registry import AGENTS, make_agent

__all__ = [
    "AVQSarsa",
    "PlanningAVQ",
    "TabularSarsa",
    "PrioritizedSweeping",
    "GridSarsa",
    "TileSarsa",
    "ActionCodebookSarsa",
    "BaseAgent",
    "NotFiniteError",
    "InvalidParameterError",
    "AGENTS",
    "make_agent",
    "load",
    "registry",
    "save_util",
    "BaseCallback",
    "CallbackList",
    "CheckpointCallback",
    "EvalCallback",
    "ProgressBarCallback",
]
