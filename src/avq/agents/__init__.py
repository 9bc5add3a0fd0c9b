"""avq's agents and the registry of agent names."""

from avq.agents.avq_plan import PlanningAVQ
from avq.agents.avq_sarsa import AVQSarsa
from avq.agents.base import BaseAgent
from avq.agents.grid import GridSarsa
from avq.agents.registry import AGENTS, make_agent
from avq.agents.save_util import load
from avq.agents.sweeping import PrioritizedSweeping
from avq.agents.tabular import TabularSarsa
from avq.agents.tiles import TileSarsa

__all__ = ["AVQSarsa", "PlanningAVQ", "TabularSarsa", "PrioritizedSweeping", "GridSarsa", "TileSarsa", "BaseAgent", "AGENTS", "make_agent", "load"]
