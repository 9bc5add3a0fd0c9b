"""avq: reinforcement learning with adaptive vector quantization.

Sarsa(λ) on a growing and merging set of Voronoi cells (Lau, Mak & Lee, 2002).
Importing avq registers its Gymnasium environments (``avq/GridMaze-v0``, ``avq/RobotMaze-v0``).

- Agents: `avq.make_agent` makes one by name (the names, their rules and their defaults:
  `avq.agents.registry`); the classes are here and in `avq.agents`; `avq.load` reads a saved one.
- Environments and maze layouts: `avq.envs`.
- Evaluation: `avq.evaluate_policy`, the mean and spread of the return over episodes (called as
  Stable-Baselines3's), and `avq.evaluate_maze`, the greedy policy from every start of a maze.
- Bad hyper-parameters raise `avq.InvalidParameterError`, a ``ValueError``.
- Sweeps of configurations and seeds, locally or on Ray or Dask: `avq.run_sweep` (the package `avq.sweep`).
- The checks every agent passes: `avq.checks`.
"""

# First: key Numba's on-disk cache by a hash of avq's sources before any compiled function is defined
# (avq._compile_cache says why; every ``import avq.x`` runs this file first).
from avq import _compile_cache

_compile_cache.configure()

from avq import (
    agents,
    checks,  # noqa: F401  (avq.checks.check_agent, the conformance checker, after ``import avq``)
    envs,  # noqa: F401  (registers the environments)
)
from avq._version import __version__
from avq.agents import *  # noqa: F403  (the agent classes, callbacks, make_agent, load: avq.agents.__all__)
from avq.evaluation import evaluate_maze, evaluate_policy
from avq.quantizer import Codebook
from avq.sweep import run_sweep

__all__ = [
    *agents.__all__,  # noqa: F405
    "Codebook",
    "evaluate_maze",
    "evaluate_policy",
    "run_sweep",
    "__version__",
    "agents",
    "envs",
    "checks",
]
