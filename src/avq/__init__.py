"""avq: reinforcement learning with adaptive vector quantization.

Sarsa(λ) on a growing and merging set of Voronoi cells (Lau, Mak & Lee, 2002).
Importing avq registers its Gymnasium environments (``avq/GridMaze-v0``, ``avq/RobotMaze-v0``).

- Agents: `avq.make_agent` makes one by name (the names, their rules and their defaults:
  `avq.agents.registry`); the classes are here and in `avq.agents`; `avq.load` reads a saved one.
- Environments and maze layouts: `avq.envs`.
- Evaluation: `avq.evaluate_maze`, the greedy policy from every start of a maze.
- Sweeps of configurations and seeds, locally or on Ray or Dask: `avq.sweep`.
- The checks every agent passes: `avq.checks`.
"""

# First: key Numba's on-disk cache by a hash of avq's sources before any compiled function is defined
# (avq._compile_cache says why; every ``import avq.x`` runs this file first).
from avq import _compile_cache

_compile_cache.configure()

from avq._version import __version__  # noqa: E402
from avq import envs  # noqa: F401  (registers the environments)
from avq.agents import (AGENTS, ActionCodebookSarsa, AVQSarsa, BaseAgent, GridSarsa, PlanningAVQ, PrioritizedSweeping, TabularSarsa,
                        TileSarsa, load, make_agent)
from avq.evaluation import evaluate_maze
from avq import checks  # noqa: F401  (avq.checks.check_agent, the conformance checker, after ``import avq``)
from avq.quantizer import Codebook

# Imported here, not lazily through a module-level __getattr__ (PEP 562): ``avq.sweep`` names both this
# function and the subpackage avq/sweep/, and the import system sets the attribute ``avq.sweep`` to the
# subpackage whenever it is first imported (``from avq.sweep import report``, the CLI, a worker). Were it
# lazy, ``avq.sweep(...)`` would then fail with "'module' object is not callable"; imported here, the
# subpackage is loaded before anything can import it, and ``avq.sweep`` stays the function. The price is
# small: avq/sweep/ imports only the standard library, NumPy and avq._io at load time (joblib, Ray, Dask,
# YAML, tqdm and Matplotlib inside the functions that use them), about 3 ms of the ~0.4 s of ``import avq``.
from avq.sweep import sweep

__all__ = [
    "AVQSarsa",
    "PlanningAVQ",
    "TabularSarsa",
    "PrioritizedSweeping",
    "GridSarsa",
    "TileSarsa",
    "ActionCodebookSarsa",
    "BaseAgent",
    "Codebook",
    "AGENTS",
    "make_agent",
    "load",
    "evaluate_maze",
    "sweep",
    "__version__",
    "agents",
    "envs",
    "checks",
]
