"""The grid maze of Lau, Mak & Lee (2002), docs/explanation/paper.md#the-maze, as a Gymnasium environment."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numba import njit

from avq.envs.layouts import Layout, LayoutSpec, check_start, layout_text, load_layout
from avq.envs.maze_starts import MazeStarts
from avq.envs.render import MazeRendering, grid_frame

__all__ = ["GridMaze", "GridDynamics", "grid_move", "slipped", "NORTH", "EAST", "SOUTH", "WEST"]

NORTH, EAST, SOUTH, WEST = 0, 1, 2, 3

GOAL_REWARD = 10.0
MOVE_REWARD = -1.0
BUMP_REWARD = -10.0


def read_only(a: np.ndarray) -> np.ndarray:
    """A read-only contiguous copy of ``a`` (the arrays of a frozen dynamics description)."""
    out = np.ascontiguousarray(a).copy()
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class GridDynamics:
    """Everything a compiled loop needs to run a :class:`GridMaze` exactly as ``step`` and ``reset`` do.

    The moves are :func:`grid_move` on these arrays; ``reset`` without options draws
    ``starts[env.np_random.integers(len(starts))]``, or takes ``fixed_start``. The step limit
    is not the maze's own: ``avq/GridMaze-v0`` gets it from Gymnasium's ``TimeLimit``.

    Attributes:
        walls: ``(H, W)`` bool, True on barriers (read-only).
        goal: the goal square ``(x, y)``.
        starts: ``(k, 2)`` int64 free non-goal squares ``(x, y)``, row-major (read-only).
        fixed_start: the start of every episode with ``start="fixed"``, else None.
        slip: the probability that a move goes sideways instead (:func:`slipped`); 0: deterministic.
        goal_reward, move_reward, bump_reward: the rewards of :func:`grid_move`.
    """

    walls: np.ndarray
    goal: tuple[int, int]
    starts: np.ndarray
    fixed_start: tuple[int, int] | None
    slip: float = 0.0
    goal_reward: float = GOAL_REWARD
    move_reward: float = MOVE_REWARD
    bump_reward: float = BUMP_REWARD


@njit(cache=True, inline="always")
def slipped(rng, a: int, slip: float) -> int:
    """The direction a move ``a`` takes: with probability ``slip`` one of the two perpendicular ones
    (equally likely), else ``a`` itself. Draws ``rng.random()``, and ``rng.integers(0, 2)`` when it slips;
    draws nothing when ``slip`` is 0."""
    if slip > 0.0 and rng.random() < slip:
        return (a + 1 + 2 * rng.integers(0, 2)) % 4
    return a


def action_index(action: Any) -> int:
    """The move ``action`` names, 0 to 3 (an integer, or a NumPy integer scalar); else a ``ValueError``."""
    a = int(action) if isinstance(action, (int, np.integer)) and not isinstance(action, bool) else -1
    if a < 0 and isinstance(action, np.ndarray) and action.shape == () and action.dtype.kind in "iu":
        a = int(action)
    if not 0 <= a < 4:
        raise ValueError(f"action must be an integer in [0, 3], not {action!r}")
    return a


@njit(cache=True, inline="always")
def grid_move(walls: np.ndarray, x: int, y: int, a: int, gx: int, gy: int) -> tuple[int, int, float, bool, bool]:
    """The maze's dynamics for one move: ``(x, y, reward, terminated, collision)`` afterwards.

    A move off the grid or onto a wall is a bump: the robot stays, reward -10.
    Otherwise the robot moves, reward -1, or +10 and the episode ends at the goal.
    """
    if a == 0:
        nx, ny = x, y - 1
    elif a == 1:
        nx, ny = x + 1, y
    elif a == 2:
        nx, ny = x, y + 1
    else:
        nx, ny = x - 1, y
    if nx < 0 or ny < 0 or ny >= walls.shape[0] or nx >= walls.shape[1] or walls[ny, nx]:
        return x, y, BUMP_REWARD, False, True
    if nx == gx and ny == gy:
        return nx, ny, GOAL_REWARD, True, False
    return nx, ny, MOVE_REWARD, False, False


class GridMaze(MazeStarts, MazeRendering, gym.Env[np.ndarray, np.int64]):
    """A robot moves on the free positions of a grid maze towards a goal.

    ## Description
    The maze of the paper (docs/explanation/paper.md#the-maze): a grid of free positions and barriers. The
    robot's state is its position ``(x, y)``; ``x`` is the column and ``y`` the
    row, both from 0 at the layout's top-left corner. Moving off the grid is a
    bump, so the layout's border need not be walls.

    ## Actions
    ``Discrete(4)``: 0 North (y - 1), 1 East (x + 1), 2 South (y + 1), 3 West (x - 1).

    ## Observations
    ``Box(float32, (2,))`` holding ``(x, y)``, bounded by the grid.

    ## Rewards
    +10 on reaching the goal; -1 for every other move; -10 for bumping into a
    wall or the grid's edge, in which case the robot stays where it is and
    ``info["collision"]`` is True.

    ## Episode end
    Terminates on reaching the goal. ``avq/GridMaze-v0`` is registered with
    ``max_episode_steps=100`` (the paper's trial length), which truncates.

    ## Arguments
    - ``layout``: preset name (``"lau2002"``, the default), file path, or list of strings.
    - ``start``: ``"random"`` (uniform over free non-goal positions, drawn from
      ``self.np_random``) or ``"fixed"`` (the layout's ``S``).
      ``reset(options={"start": (x, y)})`` starts at a given free position.
    - ``slip``: in [0, 1). With this probability a move goes in one of the two directions
      perpendicular to the one asked for (equally likely, drawn from ``self.np_random``), as
      FrozenLake's ``is_slippery``; a move that slips into a wall is a bump. 0 (the default, the
      paper's maze): deterministic, and ``step`` draws nothing.
    - ``render_mode``: ``"ansi"`` or ``"rgb_array"``.

    ## Info
    ``collision`` (bool) and ``distance`` (shortest-path steps to the goal from
    the new position). ``self.layout.distances`` holds all of them.
    """

    metadata = {"render_modes": MazeRendering.RENDER_MODES, "render_fps": 8}

    def __init__(
        self,
        layout: LayoutSpec = "lau2002",
        start: str = "random",
        slip: float = 0.0,
        render_mode: str | None = None,
    ) -> None:
        self.layout: Layout = load_layout(layout)
        check_start(self.layout, start)
        if (
            isinstance(slip, bool)
            or not isinstance(slip, (int, float, np.integer, np.floating))
            or not 0.0 <= float(slip) < 1.0
        ):
            raise ValueError(f"slip must be a probability in [0, 1), not {slip!r} (0: deterministic moves)")
        self._set_render_mode(render_mode)
        self._start_mode = start
        h, w = self.layout.height, self.layout.width
        self.observation_space = spaces.Box(
            low=np.zeros(2, dtype=np.float32),
            high=np.array([w - 1, h - 1], dtype=np.float32),
            dtype=np.float32,
        )
        self.action_space = spaces.Discrete(4)
        self._starts = self.layout.free_positions(include_goal=False)
        self._dist = self.layout.distances.tolist()
        self._gx, self._gy = self.layout.goal
        self._x, self._y = 0, 0
        fixed_start = None
        if start == "fixed" and self.layout.start is not None:  # (check_start: "fixed" needs a start)
            fixed_start = (int(self.layout.start[0]), int(self.layout.start[1]))
        self.dynamics = GridDynamics(
            walls=read_only(self.layout.walls),
            goal=(int(self._gx), int(self._gy)),
            starts=read_only(self._starts.astype(np.int64)),
            fixed_start=fixed_start,
            slip=float(slip),
        )
        """The maze's dynamics as frozen data (a ``GridDynamics``, src/avq/envs/grid_maze.py), for compiled loops."""

    # -- Gymnasium API -------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: at ``options["start"]``, a free non-goal ``(x, y)``, when given; else as ``start``
        says. A ``seed`` seeds ``self.np_random`` first (Gymnasium's rule). Returns the observation and the info."""
        super().reset(seed=seed)
        self._x, self._y = self._start_position(options)
        return self._obs(), self._info(False)

    def step(self, action: int | np.integer) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Move one square towards ``action`` (0 North, 1 East, 2 South, 3 West; sideways with probability ``slip``).

        Returns ``(observation, reward, terminated, truncated, info)`` as the class describes; ``truncated`` is
        always False here: the ``TimeLimit`` of ``avq/GridMaze-v0`` truncates.
        """
        a = action_index(action)
        if self.dynamics.slip > 0.0:  # (the compiled rule run by Python: a Generator is slow to hand to Numba)
            a = slipped.py_func(self.np_random, a, self.dynamics.slip)
        self._x, self._y, reward, terminated, collision = grid_move(
            self.layout.walls, self._x, self._y, a, self._gx, self._gy
        )
        return self._obs(), reward, terminated, False, self._info(collision)

    # -- helpers -----------------------------------------------------------------------
    @property
    def position(self) -> tuple[int, int]:
        """The robot's current ``(x, y)``."""
        return self._x, self._y

    def place(self, x: int, y: int) -> None:
        """Put the robot on square ``(x, y)`` without starting an episode.

        For a loop that ran :attr:`dynamics` itself and hands the episode back to
        ``step`` (avq's fused training): the episode goes on from there.
        """
        self._x, self._y = int(x), int(y)

    def _random_start(self) -> tuple[int, int]:
        x, y = self._starts[self.np_random.integers(len(self._starts))]
        return int(x), int(y)

    def _checked_start(self, start: Any) -> tuple[int, int]:
        try:
            x, y = start
            if any(float(v) != int(v) for v in (x, y)):
                raise ValueError
            x, y = int(x), int(y)
        except (TypeError, ValueError):
            raise ValueError(f"options['start'] must be a pair of integers (x, y), not {start!r}") from None
        if not (0 <= x < self.layout.width and 0 <= y < self.layout.height):
            raise ValueError(
                f"options['start']=({x}, {y}) is outside the {self.layout.width}x{self.layout.height} maze"
            )
        if self.layout.walls[y, x]:
            raise ValueError(f"options['start']=({x}, {y}) is on a wall; choose a free position")
        if (x, y) == self.layout.goal:
            raise ValueError(f"options['start']=({x}, {y}) is the goal; choose a free non-goal position")
        return x, y

    def _obs(self) -> np.ndarray:
        return np.array((self._x, self._y), dtype=np.float32)

    def _info(self, collision: bool) -> dict[str, Any]:
        return {"collision": collision, "distance": self._dist[self._y][self._x]}

    def _render_text(self) -> str:
        return layout_text(self.layout, self.position)

    def _render_rgb(self, cell: int = 16) -> np.ndarray:
        return grid_frame(self.layout, self.position, cell)
