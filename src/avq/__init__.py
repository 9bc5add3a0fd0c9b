"""avq: reinforcement learning with adaptive vector quantization.

Sarsa(λ) on a growing and merging set of Voronoi cells (Lau, Mak & Lee, 2002).
Importing avq registers its Gymnasium environments (``avq/GridMaze-v0``, ``avq/RobotMaze-v0``).
"""

__version__ = "0.1.0"

from avq import envs  # noqa: E402,F401  (registers the environments)
from avq.agents import AGENTS, AVQSarsa, BaseAgent, GridSarsa, TabularSarsa, TileSarsa, load, make_agent  # noqa: E402
from avq.evaluation import evaluate_maze  # noqa: E402
from avq.quantizer import Codebook  # noqa: E402
from avq.sweep import sweep  # noqa: E402

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
