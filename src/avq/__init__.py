"""avq: reinforcement learning with adaptive vector quantization.

Sarsa(λ) on a growing and merging set of Voronoi cells (Lau, Mak & Lee, 2002).
Importing avq registers its Gymnasium environments (``avq/GridMaze-v0``, ``avq/RobotMaze-v0``).
"""

from avq._version import __version__
from avq import envs  # noqa: F401  (registers the environments)
from avq.agents import AGENTS, AVQSarsa, BaseAgent, GridSarsa, TabularSarsa, TileSarsa, load, make_agent
from avq.evaluation import evaluate_maze
from avq.quantizer import Codebook
from avq.sweep import sweep

__all__ = [
    "AVQSarsa",
    "TabularSarsa",
    "GridSarsa",
    "TileSarsa",
    "BaseAgent",
    "Codebook",
    "AGENTS",
    "make_agent",
    "load",
    "evaluate_maze",
    "sweep",
    "__version__",
]
