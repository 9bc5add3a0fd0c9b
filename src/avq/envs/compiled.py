"""The contract between avq's mazes and the compiled loops that run them.

A loop that runs a maze's dynamics itself (avq's fused training, the greedy walks of
:func:`avq.evaluate_maze`) reads the maze only through this module and the maze's
public :attr:`~avq.envs.GridMaze.dynamics` (a frozen :class:`~avq.envs.grid_maze.GridDynamics`
or :class:`~avq.envs.robot_geometry.RobotDynamics`). :func:`compiled_maze` unwraps an
environment made by ``gymnasium.make`` and gives a :class:`CompiledMaze`: the dynamics,
the step limit in force, the generator that draws the starts, and the episode's state
(position and elapsed steps) to read before such a loop runs and to write back after it,
so that ``env.step`` goes on from where the loop stopped.

Gymnasium's own wrappers keep their meaning: the limit of a ``TimeLimit`` applies, and its
count of elapsed steps is the one read and written. Those counts are private attributes of
Gymnasium's wrappers; this module is the one place in avq that touches them.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit

from avq.envs.grid_maze import GridDynamics, GridMaze
from avq.envs.robot_geometry import RobotDynamics
from avq.envs.robot_maze import RobotMaze

__all__ = ["CompiledMaze", "compiled_maze", "NO_LIMIT"]

#: The step limit of an episode that nothing truncates.
NO_LIMIT = 1 << 62


@dataclass(frozen=True)
class CompiledMaze:
    """A maze environment seen by a loop that runs its dynamics itself.

    Attributes:
        maze: the maze (``env.unwrapped``).
        dynamics: ``maze.dynamics``.
        max_episode_steps: the step limit in force: the smallest of the ``TimeLimit`` wrappers'
            (``gymnasium.make``'s and any of your own) and, for RobotMaze, its own ``max_steps``;
            :data:`NO_LIMIT` without any.
    """

    maze: GridMaze | RobotMaze
    dynamics: GridDynamics | RobotDynamics
    max_episode_steps: int
    _time_limits: tuple[TimeLimit, ...]
    _order: OrderEnforcing | None

    @property
    def np_random(self) -> np.random.Generator:
        """The maze's generator, from which ``reset`` draws the starts."""
        return self.maze.np_random

    def episode_state(self) -> tuple[float, float, int]:
        """The robot's position and the steps elapsed in the current episode (by the ``TimeLimit``'s
        count where there is one)."""
        x, y = self.maze.position
        if self._time_limits:
            elapsed = self._time_limits[0]._elapsed_steps or 0  # (the wrappers count together: one reset, one step)
        elif isinstance(self.maze, RobotMaze):
            elapsed = self.maze.elapsed_steps
        else:
            elapsed = 0
        return x, y, int(elapsed)

    def set_episode_state(self, x: float, y: float, elapsed: int) -> None:
        """Put the robot at ``(x, y)``, ``elapsed`` steps into an episode that ``env.step`` continues."""
        if isinstance(self.maze, RobotMaze):
            self.maze.place(x, y, elapsed)
        else:
            self.maze.place(int(x), int(y))
        for time_limit in self._time_limits:
            # (Gymnasium sets ``_elapsed_steps = None`` in TimeLimit.__init__, so its type is inferred as None)
            time_limit._elapsed_steps = int(elapsed)  # type: ignore[assignment]
        if self._order is not None:
            self._order._has_reset = True  # the loop's episode was started by a reset of its own


def compiled_maze(env: gym.Env) -> CompiledMaze | None:
    """``env`` as a :class:`CompiledMaze`, if it is a :class:`GridMaze` or :class:`RobotMaze` (not a
    subclass, which may step differently) under Gymnasium's standard wrappers only (``TimeLimit``,
    any number of them, ``OrderEnforcing``, ``PassiveEnvChecker``); else None."""
    time_limits: list[TimeLimit] = []
    order = None
    e = env
    while isinstance(e, gym.Wrapper):
        if isinstance(e, TimeLimit):
            time_limits.append(e)
        elif isinstance(e, OrderEnforcing):
            order = e
        elif not isinstance(e, PassiveEnvChecker):
            return None
        e = e.env
    if type(e) is not GridMaze and type(e) is not RobotMaze:
        return None
    limit = min([t._max_episode_steps for t in time_limits], default=NO_LIMIT)
    if isinstance(e, RobotMaze):
        limit = min(limit, e.dynamics.max_steps)
    return CompiledMaze(e, e.dynamics, int(limit), tuple(time_limits), order)
