"""The paper's robot in a continuous maze (docs/explanation/paper.md#the-maze) as a Gymnasium environment: a disc with a ring of 16 sonars.

:class:`RobotMaze` keeps the state, checks its arguments and answers the Gymnasium API; what a
move, a collision or a sonar range is lives in :mod:`avq.envs.robot_geometry`, compiled, where
avq's compiled loops call the same functions on the env's frozen :class:`RobotDynamics`, and
its pictures in :mod:`avq.envs.render`. The names of those modules that code imported from
here before they moved (``RobotDynamics``, ``robot_move``, ``random_start``, ``sonar_ranges``,
``sonar_directions``, ``N_SONARS``) can still be imported from here.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq.envs.grid_maze import EAST, NORTH, SOUTH, WEST, action_index, read_only
from avq.envs.layouts import Layout, LayoutSpec, check_start, layout_text, load_layout
from avq.envs.maze_starts import MazeStarts
from avq.envs.render import MazeRendering, robot_frame
from avq.envs.robot_geometry import (
    EPS,
    N_SONARS,
    RobotDynamics,
    disc_collides,
    in_goal,
    lattice_distances,
    padded_walls,
    random_start,
    robot_move,
    sonar_directions,
    sonar_ranges,
)

__all__ = [
    "RobotMaze",
    "RobotDynamics",
    "robot_move",
    "random_start",
    "sonar_ranges",
    "N_SONARS",
    "NORTH",
    "EAST",
    "SOUTH",
    "WEST",
]


class RobotMaze(MazeStarts, MazeRendering, gym.Env[np.ndarray, np.int64]):
    """A disc-shaped robot with 16 sonars moves through a continuous maze towards a goal.

    ## Description
    The paper's robot (docs/explanation/paper.md#the-maze, a Nomad 200 with a ring of 16 sonars) in a
    continuous version of GridMaze's layouts. Each layout character is a unit
    square centred at GridMaze's integer position ``(x, y)`` (column, row; ``y``
    grows downwards): ``#`` squares are obstacles, and the maze is the rectangle
    ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``. The robot is a disc of ``radius``
    centred at its continuous position ``(x, y)``.

    ## Actions
    ``Discrete(4)``: 0 North (y - move), 1 East (x + move), 2 South (y + move),
    3 West (x - move).

    ## Observations
    ``Box(float32, (2,))`` holding ``(x, y)``, bounded by the maze rectangle. With
    ``observe_sonar=True``, ``Box(float32, (18,))``: ``(x, y)`` and then the 16
    sonar ranges (bounds 0 and ``sonar_range``).

    ## Rewards
    A move whose end position would make the disc overlap an obstacle square
    (distance from the centre to the square below ``radius``; touching is allowed)
    or leave the maze is a collision: -10, and the robot **stays where it was**
    (it does not stop at the point of contact), with ``info["collision"]`` True.
    Any other move: -1, or +10 when the new centre lies in the closed goal square.
    Only the end position is tested; as squares are whole units and
    ``move <= 1``, a move cannot jump across an obstacle.

    ## Episode end
    Terminates when the centre reaches the goal square. The env truncates by
    itself after ``max_steps`` steps (exposed as ``self.max_steps``), default
    ``ceil(100 / move)``: 400 at ``move=0.25``, the same distance as GridMaze's
    100 steps of one unit. Because the limit scales with ``move``,
    ``avq/RobotMaze-v0`` is registered *without* ``max_episode_steps``. As with
    Gymnasium's ``TimeLimit``, the last step may be both terminated and truncated.

    ## Sonar
    Beam ``k`` points at compass bearing ``k * 22.5`` degrees clockwise from North
    (beam 0 North, 4 East, 8 South, 12 West). Its range is the distance from the
    robot's surface (centre distance minus ``radius``) along the ray to the first
    obstacle square or the maze's edge, computed exactly by grid traversal and
    clipped to ``[0, sonar_range]``; a beam that grazes an obstacle's edge or
    corner stops there. With ``sonar_noise > 0``, Gaussian noise of that standard
    deviation from ``self.np_random`` is added and the result clipped again
    (without noise, no random numbers are drawn).

    ## Arguments
    - ``layout``: anything :func:`avq.envs.load_layout` accepts (default ``"lau2002"``).
    - ``start``: ``"random"``: a free non-goal square uniformly, then a uniform
      position inside it, drawn again until the disc overlaps no obstacle (all
      from ``self.np_random``); ``"fixed"``: the centre of the layout's ``S``.
      ``reset(options={"start": (x, y)})`` starts at any position where the disc
      fits inside the maze, overlaps no obstacle, and the centre is not in the goal
      square.
    - ``radius`` in (0, 0.5); ``move`` in (0, 1]; ``sonar_range`` > 0 (finite);
      ``sonar_noise`` >= 0; ``observe_sonar``; ``max_steps`` (None or >= 1);
      ``render_mode``: ``"ansi"`` or ``"rgb_array"``.

    ## Info
    ``collision`` (bool); ``distance``: GridMaze's shortest-path steps to the goal
    from the square containing the centre (``layout.distances``; on a boundary
    between squares the one East/South of it, except that the goal square wins);
    ``sonar``: the 16 ranges, float32.

    ## Evaluation
    :meth:`start_positions` gives the centres of the free non-goal squares and
    :meth:`shortest_steps` the exact least number of moves from a position to the
    goal (a breadth-first search over the lattice of positions reachable from it).
    """

    metadata = {"render_modes": MazeRendering.RENDER_MODES, "render_fps": 16}

    def __init__(
        self,
        layout: LayoutSpec = "lau2002",
        start: str = "random",
        radius: float = 0.2,
        move: float = 0.25,
        sonar_range: float = 5.0,
        sonar_noise: float = 0.0,
        observe_sonar: bool = False,
        max_steps: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        self.layout: Layout = load_layout(layout)
        check_start(self.layout, start)
        radius = _number("radius", radius)
        if not 0.0 < radius < 0.5:
            raise ValueError(f"radius must be in (0, 0.5) so that the robot fits in a square, not {radius}")
        move = _number("move", move)
        if not 0.0 < move <= 1.0:
            raise ValueError(f"move must be in (0, 1], not {move}")
        sonar_range = _number("sonar_range", sonar_range)
        if not (0.0 < sonar_range < math.inf):
            raise ValueError(f"sonar_range must be a finite number > 0, not {sonar_range}")
        sonar_noise = _number("sonar_noise", sonar_noise)
        if not 0.0 <= sonar_noise < math.inf:
            raise ValueError(f"sonar_noise must be a finite number >= 0, not {sonar_noise}")
        if max_steps is None:
            # ceil(100 / move), guarded against 100 / move landing a hair above an integer.
            max_steps = math.ceil(100.0 / move - EPS)
        elif isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
            raise ValueError(f"max_steps must be None or an integer >= 1, not {max_steps!r}")
        self._set_render_mode(render_mode)
        if not isinstance(observe_sonar, (bool, np.bool_)):
            raise ValueError(f"observe_sonar must be True or False, not {observe_sonar!r}")
        observe_sonar = bool(observe_sonar)
        self._start_mode = start

        h, w = self.layout.height, self.layout.width
        low = [-0.5, -0.5]
        high = [w - 0.5, h - 0.5]
        if observe_sonar:
            low += [0.0] * N_SONARS
            high += [sonar_range] * N_SONARS
        self.observation_space = spaces.Box(
            low=np.array(low, dtype=np.float32), high=np.array(high, dtype=np.float32), dtype=np.float32
        )
        self.action_space = spaces.Discrete(4)

        self._grid = padded_walls(self.layout.walls)
        self._dirs = sonar_directions()
        self._starts = self.layout.free_positions(include_goal=False)
        self._dist = self.layout.distances
        self._gx, self._gy = (float(v) for v in self.layout.goal)
        self._x, self._y = 0.0, 0.0
        self._steps = 0
        self._sonar = np.zeros(N_SONARS, dtype=np.float64)
        # shortest_steps: lattice origin (rounded) -> (x0, y0, distances).
        self._lattices: dict[tuple[float, float], tuple[float, float, np.ndarray]] = {}
        fixed_start = None
        if start == "fixed" and self.layout.start is not None:  # (check_start: "fixed" needs a start)
            fixed_start = (float(self.layout.start[0]), float(self.layout.start[1]))
        self.dynamics = RobotDynamics(
            grid=read_only(self._grid),
            goal=(self._gx, self._gy),
            starts=read_only(self._starts.astype(np.int64)),
            fixed_start=fixed_start,
            move=move,
            radius=radius,
            sonar_directions=read_only(self._dirs),
            sonar_range=sonar_range,
            sonar_noise=sonar_noise,
            observe_sonar=observe_sonar,
            max_steps=int(max_steps),
        )
        """The maze's dynamics as frozen data (a ``RobotDynamics``, src/avq/envs/robot_geometry.py), for compiled loops."""

    # -- Gymnasium API -------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: at ``options["start"]``, an ``(x, y)`` where the disc fits, when given; else as
        ``start`` says. A ``seed`` seeds ``self.np_random`` first (Gymnasium's rule). Returns the observation and
        the info."""
        super().reset(seed=seed)
        self._x, self._y = self._start_position(options)
        self._steps = 0
        self._sense()
        return self._obs(), self._info(False)

    def step(self, action: int | np.integer) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Move ``move`` towards ``action`` (0 North, 1 East, 2 South, 3 West), unless the disc would collide.

        Returns ``(observation, reward, terminated, truncated, info)`` as the class describes; ``truncated``
        after ``max_steps`` steps.
        """
        a = action_index(action)
        self._steps += 1
        self._x, self._y, reward, terminated, collision = robot_move(
            self._grid, self._x, self._y, a, self.move, self.radius, self._gx, self._gy
        )
        truncated = self._steps >= self.max_steps
        self._sense()
        return self._obs(), reward, terminated, truncated, self._info(collision)

    # -- evaluation ----------------------------------------------------------------------
    def start_positions(self) -> np.ndarray:
        """Centres of all free non-goal squares, ``(k, 2)`` float64 of ``(x, y)``, row-major order."""
        return self._starts.astype(np.float64)

    def shortest_steps(self, x: float, y: float) -> int:
        """Exact least number of moves from ``(x, y)`` to the goal square; -1 if unreachable.

        Breadth-first search over the lattice ``(x + i * move, y + j * move)`` inside
        the maze, with the collision rule of :meth:`step`. The search is cached per
        lattice (its offset, to 1e-9), so asking for every start of one lattice
        costs one search. 0 when the centre is already in the goal square.

        Raises:
            ValueError: if the disc does not fit at ``(x, y)``.
        """
        x, y = self._checked_position((x, y), "shortest_steps position", allow_goal=True)
        m = self.move
        # Lattice origin: the lowest lattice coordinate not below the maze's edge.
        x0 = x - math.floor((x + 0.5) / m + EPS) * m
        y0 = y - math.floor((y + 0.5) / m + EPS) * m
        key = (round(x0, 9), round(y0, 9))
        if key not in self._lattices:
            self._lattices[key] = (x0, y0, self._lattice_search(x0, y0))
        x0, y0, dist = self._lattices[key]
        i = round((x - x0) / m)
        j = round((y - y0) / m)
        return int(dist[j, i])

    def _lattice_search(self, x0: float, y0: float) -> np.ndarray:
        m, r = self.move, self.radius
        nx = math.floor((self.layout.width - 0.5 - x0) / m + EPS) + 1
        ny = math.floor((self.layout.height - 0.5 - y0) / m + EPS) + 1
        valid = np.zeros((ny, nx), dtype=np.bool_)
        goal = np.zeros((ny, nx), dtype=np.bool_)
        for j in range(ny):
            y = y0 + j * m
            for i in range(nx):
                x = x0 + i * m
                if not disc_collides(self._grid, x, y, r):
                    valid[j, i] = True
                    goal[j, i] = in_goal(x, y, self._gx, self._gy)
        return lattice_distances(valid, goal)

    # -- helpers -----------------------------------------------------------------------
    @property
    def position(self) -> tuple[float, float]:
        """The robot's current centre ``(x, y)``."""
        return self._x, self._y

    # The arguments, read-only (and ``start``): the frozen dynamics hold them, so that what ``step`` does and
    # what a compiled loop does cannot drift apart.
    radius = property(lambda self: self.dynamics.radius, doc="The robot's radius.")
    move = property(lambda self: self.dynamics.move, doc="The length of a move.")
    sonar_range = property(lambda self: self.dynamics.sonar_range, doc="The sonar's range.")
    sonar_noise = property(lambda self: self.dynamics.sonar_noise, doc="The sonar's noise (standard deviation).")
    observe_sonar = property(lambda self: self.dynamics.observe_sonar, doc="Whether the sonar is observed.")
    max_steps = property(lambda self: self.dynamics.max_steps, doc="The step limit of an episode (the env truncates).")

    @property
    def elapsed_steps(self) -> int:
        """Steps taken in the current episode (the maze truncates at ``max_steps``)."""
        return self._steps

    def place(self, x: float, y: float, elapsed_steps: int) -> None:
        """Put the robot at ``(x, y)``, ``elapsed_steps`` into the episode, without starting one.

        For a loop that ran :attr:`dynamics` itself and hands the episode back to
        ``step`` (avq's fused training): the episode goes on from there. The sonar is
        read again at the new position.
        """
        self._x, self._y, self._steps = float(x), float(y), int(elapsed_steps)
        self._sense()

    @property
    def sonar(self) -> np.ndarray:
        """The latest sonar ranges (a float32 copy)."""
        return self._sonar.astype(np.float32)

    def _random_start(self) -> tuple[float, float]:
        return random_start(self.np_random, self._starts, self._grid, self.radius, self._gx, self._gy)

    def _checked_start(self, start: Any) -> tuple[float, float]:
        return self._checked_position(start, "options['start']", allow_goal=False)

    def _checked_position(self, pos: Any, what: str, allow_goal: bool) -> tuple[float, float]:
        try:
            x, y = pos
            x, y = float(x), float(y)
        except (TypeError, ValueError):
            raise ValueError(f"{what} must be a pair of numbers (x, y), not {pos!r}") from None
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"{what}=({x}, {y}) must be finite")
        w, h, r = self.layout.width, self.layout.height, self.radius
        if not (-0.5 + r <= x + EPS and x - EPS <= w - 0.5 - r and -0.5 + r <= y + EPS and y - EPS <= h - 0.5 - r):
            raise ValueError(
                f"{what}=({x}, {y}) puts the robot (radius {r}) outside the maze [-0.5, {w - 0.5}] x [-0.5, {h - 0.5}]"
            )
        if disc_collides(self._grid, x, y, r):
            raise ValueError(f"{what}=({x}, {y}): the robot (radius {r}) would overlap a wall")
        if not allow_goal and in_goal(x, y, self._gx, self._gy):
            raise ValueError(f"{what}=({x}, {y}) is in the goal square; choose a position outside it")
        return x, y

    def _square(self) -> tuple[int, int]:
        """The layout square containing the centre (the goal square wins on its boundary)."""
        if in_goal(self._x, self._y, self._gx, self._gy):
            return int(self._gx), int(self._gy)
        i = min(max(math.floor(self._x + 0.5), 0), self.layout.width - 1)
        j = min(max(math.floor(self._y + 0.5), 0), self.layout.height - 1)
        return i, j

    def _sense(self) -> None:
        sonar_ranges(self._grid, self._x, self._y, self.radius, self._dirs, self.sonar_range, self._sonar)
        if self.sonar_noise > 0.0:
            self._sonar += self.np_random.normal(0.0, self.sonar_noise, size=N_SONARS)
            np.clip(self._sonar, 0.0, self.sonar_range, out=self._sonar)

    def _obs(self) -> np.ndarray:
        if not self.observe_sonar:
            return np.array((self._x, self._y), dtype=np.float32)
        obs = np.empty(2 + N_SONARS, dtype=np.float32)
        obs[0], obs[1] = self._x, self._y
        obs[2:] = self._sonar
        return obs

    def _info(self, collision: bool) -> dict[str, Any]:
        i, j = self._square()
        return {"collision": collision, "distance": int(self._dist[j, i]), "sonar": self.sonar}

    def _render_text(self) -> str:
        return layout_text(self.layout, self._square())

    def _render_rgb(self, scale: int = 32) -> np.ndarray:
        """Walls dark, goal green, the robot a red disc, each beam a line from its surface to its range."""
        return robot_frame(self.layout, self._x, self._y, self.radius, self._dirs, self._sonar, scale)


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a number, not {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, not {value!r}") from None
