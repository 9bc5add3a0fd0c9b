"""The paper's robot in a continuous maze (SPEC §6): a disc with a ring of 16 sonars.

The dynamics are small module-level functions over plain NumPy arrays and
floats (``disc_collides``, ``in_goal``, ``cast_ray``, ``sonar_ranges``,
``lattice_distances``), written so that Numba can compile them as they are;
:class:`RobotMaze` only keeps the state and calls them.

Geometry: the layout character at column ``x``, row ``y`` is the closed unit
square ``[x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]``, so square centres are
GridMaze's integer positions, and the maze is the rectangle
``[-0.5, W - 0.5] x [-0.5, H - 0.5]``. ``y`` grows downwards. The kernels work
on the *padded* wall grid (:func:`padded_walls`): one ring of wall squares
around the layout, so that the maze's edge is just another wall and no loop
needs a bounds check. Padded cell ``(i, j)`` covers world
``[i - 1.5, i - 0.5] x [j - 1.5, j - 0.5]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numba import njit

from avq.envs.grid_maze import (
    BUMP_REWARD,
    EAST,
    GOAL_REWARD,
    MOVE_REWARD,
    NORTH,
    SOUTH,
    WEST,
    action_index,
    read_only,
)
from avq.envs.layouts import COLOURS, Layout, LayoutSpec, check_start, layout_image, layout_text, load_layout

__all__ = ["RobotMaze", "RobotDynamics", "robot_move", "random_start", "sonar_ranges", "N_SONARS", "NORTH", "EAST",
           "SOUTH", "WEST"]

#: Number of sonar beams (the Sensus 300 ring of the Nomad 200, SPEC §6).
N_SONARS = 16

#: Rounding tolerance of every geometric comparison (touching, goal square).
#: Positions are sums of moves, so "exactly touching" may be off by a few ulps.
EPS = 1e-9

_COLOURS = {**COLOURS, "beam": (240, 170, 20)}


# -- kernels (plain arrays and floats; Numba-ready) ------------------------------------


def padded_walls(walls: np.ndarray) -> np.ndarray:
    """The layout's ``(H, W)`` wall mask inside a one-square ring of walls: ``(H + 2, W + 2)``."""
    h, w = walls.shape
    grid = np.ones((h + 2, w + 2), dtype=np.bool_)
    grid[1:-1, 1:-1] = walls
    return grid


def sonar_directions() -> np.ndarray:
    """Unit vectors ``(dx, dy)`` of the 16 beams, ``(16, 2)`` float64.

    Beam ``k`` points at compass bearing ``k * 22.5`` degrees clockwise from North
    (``-y``): beam 0 North, 4 East (``+x``), 8 South, 12 West. Components on the
    axes are exactly 0 or 1 and the diagonal beams have exactly equal components,
    so that a beam along a grid line or through a grid corner stays on it.
    """
    # |sin| and |cos| of multiples of 22.5 degrees take only these five values.
    mags = (0.0, math.sin(math.pi / 8), math.sqrt(0.5), math.cos(math.pi / 8), 1.0)
    dirs = np.zeros((N_SONARS, 2), dtype=np.float64)
    for k in range(N_SONARS):
        theta = k * math.pi / 8
        m = k % 8
        s, c = mags[4 - abs(4 - m)], mags[abs(4 - m)]
        dirs[k, 0] = math.copysign(s, math.sin(theta)) if s else 0.0
        dirs[k, 1] = math.copysign(c, -math.cos(theta)) if c else 0.0
    return dirs


@njit(cache=True)
def disc_collides(grid: np.ndarray, x: float, y: float, radius: float) -> bool:
    """Whether a disc at ``(x, y)`` overlaps a wall square or leaves the maze.

    Overlap means the distance from the centre to the (closed) square is below
    ``radius``; touching at exactly ``radius`` is allowed (up to :data:`EPS`).

    Args:
        grid: Padded wall grid (:func:`padded_walls`).
        x, y: The disc's centre, world coordinates.
        radius: The disc's radius, in (0, 0.5).
    """
    u = x + 1.5
    v = y + 1.5
    # The maze rectangle is [1, W + 1] x [1, H + 1] in padded coordinates.
    if u - radius < 1.0 - EPS or v - radius < 1.0 - EPS:
        return True
    if u + radius > grid.shape[1] - 1 + EPS or v + radius > grid.shape[0] - 1 + EPS:
        return True
    r2 = (radius - EPS) * (radius - EPS)
    for j in range(math.floor(v - radius), math.floor(v + radius) + 1):
        for i in range(math.floor(u - radius), math.floor(u + radius) + 1):
            if grid[j, i]:
                ddx = max(i - u, 0.0, u - (i + 1))
                ddy = max(j - v, 0.0, v - (j + 1))
                if ddx * ddx + ddy * ddy < r2:
                    return True
    return False


@njit(cache=True, inline="always")
def in_goal(x: float, y: float, gx: float, gy: float) -> bool:
    """Whether the centre ``(x, y)`` lies in the closed goal square centred at ``(gx, gy)``."""
    return abs(x - gx) <= 0.5 + EPS and abs(y - gy) <= 0.5 + EPS


@njit(cache=True, inline="always")
def _axis(u: float, d: float):
    """One axis of :func:`cast_ray`'s traversal from coordinate ``u`` along ``d``: the step (+1, -1, 0),
    the offset of the next grid line (1 or 0), the current index, the first and last index touched
    (two when the ray runs along a grid line, ``d == 0``) and the time of the next grid line."""
    if d != 0.0:
        step = 1 if d > 0.0 else -1
        off = 1 if d > 0.0 else 0
        i = math.floor(u) if d > 0.0 else math.ceil(u) - 1
        return step, off, i, i, i, (i + off - u) / d
    lo = math.ceil(u) - 1
    return 0, 0, lo, lo, math.floor(u), math.inf


@njit(cache=True)
def cast_ray(grid: np.ndarray, x: float, y: float, dx: float, dy: float, t_max: float) -> float:
    """Distance from ``(x, y)`` along the unit vector ``(dx, dy)`` to the first wall, at most ``t_max``.

    Exact grid traversal (Amanatides & Woo's DDA) over the padded grid. Wall squares
    are closed: a ray that grazes a wall's edge or passes exactly through its corner
    stops there. Between two grid-line crossings the ray touches one column (two,
    ``xa`` and ``xb``, when it runs along a vertical grid line, ``dx == 0``) and one
    row (likewise). Crossing a vertical line it enters the next column, crossing a
    horizontal line the next row, and crossing both at once (a corner) it touches
    the three other cells around the corner. Only newly touched cells are tested:
    the start ``(x, y)`` must not lie in a wall square, so all earlier ones are free.
    """
    u = x + 1.5
    v = y + 1.5
    # Columns: ix is the current one, tx the time of the next vertical grid line
    # (at u = ix + bx); likewise rows.
    sx, bx, ix, xa, xb, tx = _axis(u, dx)
    sy, by, iy, ya, yb, ty = _axis(v, dy)
    while True:
        if tx < ty:  # into the next column
            if tx >= t_max:
                return t_max
            c = ix + sx
            if grid[ya, c] or (yb != ya and grid[yb, c]):
                return tx
            ix = xa = xb = c
            tx = (ix + bx - u) / dx
        elif ty < tx:  # into the next row
            if ty >= t_max:
                return t_max
            r = iy + sy
            if grid[r, xa] or (xb != xa and grid[r, xb]):
                return ty
            iy = ya = yb = r
            ty = (iy + by - v) / dy
        else:  # through a corner (dx and dy both non-zero here)
            if tx >= t_max:
                return t_max
            c = ix + sx
            r = iy + sy
            if grid[iy, c] or grid[r, ix] or grid[r, c]:
                return tx
            ix = xa = xb = c
            iy = ya = yb = r
            tx = (ix + bx - u) / dx
            ty = (iy + by - v) / dy


@njit(cache=True)
def sonar_ranges(
    grid: np.ndarray, x: float, y: float, radius: float, dirs: np.ndarray, max_range: float, out: np.ndarray
) -> np.ndarray:
    """Noise-free sonar ranges into ``out``: from the disc's surface to the first wall, in ``[0, max_range]``."""
    t_max = max_range + radius
    for k in range(dirs.shape[0]):
        r = cast_ray(grid, x, y, dirs[k, 0], dirs[k, 1], t_max) - radius
        out[k] = 0.0 if r < 0.0 else min(r, max_range)
    return out


@njit(cache=True, inline="always")
def robot_move(grid: np.ndarray, x: float, y: float, a: int, move: float, radius: float, gx: float, gy: float):
    """One move of the robot: ``(x, y, reward, terminated, collision)`` afterwards.

    A move that would make the disc overlap a wall or leave the maze is a collision:
    the robot stays where it was, reward -10. Otherwise it moves, reward -1, or +10
    and the episode ends when its centre enters the goal square.
    """
    nx, ny = x, y
    if a == 0:
        ny = y + -move
    elif a == 1:
        nx = x + move
    elif a == 2:
        ny = y + move
    else:
        nx = x + -move
    if disc_collides(grid, nx, ny, radius):
        return x, y, BUMP_REWARD, False, True
    if in_goal(nx, ny, gx, gy):
        return nx, ny, GOAL_REWARD, True, False
    return nx, ny, MOVE_REWARD, False, False


@njit(cache=True)
def random_start(rng, starts: np.ndarray, grid: np.ndarray, radius: float, gx: float, gy: float):
    """A uniform free non-goal square, then a uniform position in it where the disc fits."""
    k = rng.integers(0, starts.shape[0])
    cx, cy = starts[k, 0], starts[k, 1]
    while True:
        u = rng.uniform(-0.5, 0.5, 2)
        x, y = cx + u[0], cy + u[1]
        if not disc_collides(grid, x, y, radius) and not in_goal(x, y, gx, gy):
            return x, y


@njit(cache=True)
def lattice_distances(valid: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Breadth-first moves to the nearest goal node on a 4-connected lattice; -1 where unreachable.

    Args:
        valid: ``(ny, nx)`` bool, True where the disc fits.
        goal: ``(ny, nx)`` bool, True where the centre is in the goal square.
    """
    ny, nx = valid.shape
    dist = np.full((ny, nx), -1, dtype=np.int64)
    queue = np.empty(ny * nx, dtype=np.int64)
    head = 0
    tail = 0
    for j in range(ny):
        for i in range(nx):
            if goal[j, i] and valid[j, i]:
                dist[j, i] = 0
                queue[tail] = j * nx + i
                tail += 1
    # A move's validity depends only on its end position, so moves are reversible
    # and a search from the goal gives every node's distance to it.
    while head < tail:
        q = queue[head]
        head += 1
        j = q // nx
        i = q - j * nx
        d = dist[j, i] + 1
        for k in range(4):
            ni = i + (0, 1, 0, -1)[k]
            nj = j + (-1, 0, 1, 0)[k]
            if 0 <= ni < nx and 0 <= nj < ny and valid[nj, ni] and dist[nj, ni] < 0:
                dist[nj, ni] = d
                queue[tail] = nj * nx + ni
                tail += 1
    return dist


# -- the environment ---------------------------------------------------------------------


@dataclass(frozen=True)
class RobotDynamics:
    """Everything a compiled loop needs to run a :class:`RobotMaze` exactly as ``step`` and ``reset`` do.

    A step is :func:`robot_move` on ``grid``, then the observation: the centre, and with
    ``observe_sonar`` the ranges of :func:`sonar_ranges` (plus Gaussian noise of
    ``sonar_noise`` from ``env.np_random``), each rounded to float32. ``reset`` without
    options draws :func:`random_start` from ``env.np_random``, or takes ``fixed_start``.
    The episode is truncated after ``max_steps`` steps.

    Attributes:
        grid: the padded wall grid ``(H + 2, W + 2)`` (:func:`padded_walls`, read-only).
        goal: the goal square's centre ``(x, y)``.
        starts: ``(k, 2)`` int64 centres of the free non-goal squares (read-only).
        fixed_start: the start of every episode with ``start="fixed"``, else None.
        move, radius: the length of a move and the robot's radius.
        sonar_directions: ``(16, 2)`` unit vectors of the beams (read-only).
        sonar_range, sonar_noise, observe_sonar: the sonar's range, noise and whether it is observed.
        max_steps: the maze's own step limit.
        goal_reward, move_reward, bump_reward: the rewards of :func:`robot_move`.
    """

    grid: np.ndarray
    goal: tuple[float, float]
    starts: np.ndarray
    fixed_start: tuple[float, float] | None
    move: float
    radius: float
    sonar_directions: np.ndarray
    sonar_range: float
    sonar_noise: float
    observe_sonar: bool
    max_steps: int
    goal_reward: float = GOAL_REWARD
    move_reward: float = MOVE_REWARD
    bump_reward: float = BUMP_REWARD



class RobotMaze(gym.Env[np.ndarray, np.int64]):
    """A disc-shaped robot with 16 sonars moves through a continuous maze towards a goal.

    ## Description
    The paper's robot (SPEC §6, a Nomad 200 with a ring of 16 sonars) in a
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

    metadata = {"render_modes": ["ansi", "rgb_array"], "render_fps": 16}

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
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, not {render_mode!r}")
        if not isinstance(observe_sonar, (bool, np.bool_)):
            raise ValueError(f"observe_sonar must be True or False, not {observe_sonar!r}")
        observe_sonar = bool(observe_sonar)
        self._start_mode = start
        self.render_mode = render_mode

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
        self.dynamics = RobotDynamics(
            grid=read_only(self._grid), goal=(self._gx, self._gy), starts=read_only(self._starts.astype(np.int64)),
            fixed_start=tuple(float(v) for v in self.layout.start) if start == "fixed" else None,
            move=move, radius=radius, sonar_directions=read_only(self._dirs),
            sonar_range=sonar_range, sonar_noise=sonar_noise, observe_sonar=observe_sonar,
            max_steps=int(max_steps),
        )
        """The maze's dynamics as frozen data (a ``RobotDynamics``, src/avq/envs/robot_maze.py), for compiled loops."""

    # -- Gymnasium API -------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: at ``options["start"]``, an ``(x, y)`` where the disc fits, when given; else as
        ``start`` says. A ``seed`` seeds ``self.np_random`` first (Gymnasium's rule). Returns the observation and
        the info."""
        super().reset(seed=seed)
        start = None if options is None else options.get("start")
        if start is not None:
            self._x, self._y = self._checked_position(start, "options['start']", allow_goal=False)
        elif self.start == "fixed":
            sx, sy = self.layout.start  # type: ignore[misc]
            self._x, self._y = float(sx), float(sy)
        else:
            self._x, self._y = self._random_start()
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
            self._grid, self._x, self._y, a, self.move, self.radius, self._gx, self._gy)
        truncated = self._steps >= self.max_steps
        self._sense()
        return self._obs(), reward, terminated, truncated, self._info(collision)

    def render(self) -> str | np.ndarray | None:
        """The maze and the robot: text with ``render_mode="ansi"``, an RGB array with ``"rgb_array"``, else None."""
        if self.render_mode == "ansi":
            return self._render_text()
        if self.render_mode == "rgb_array":
            return self._render_rgb()
        return None

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

    # The arguments, read-only: the frozen dynamics hold them, so that what ``step`` does and what a
    # compiled loop does cannot drift apart.
    @property
    def start(self) -> str:
        """``"random"`` or ``"fixed"``."""
        return self._start_mode

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
                f"{what}=({x}, {y}) puts the robot (radius {r}) outside the maze "
                f"[-0.5, {w - 0.5}] x [-0.5, {h - 0.5}]"
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
        img = layout_image(self.layout, scale)
        hp, wp = img.shape[:2]

        def to_px(v: np.ndarray) -> np.ndarray:  # world coordinate -> pixel index
            return np.floor((v + 0.5) * scale).astype(np.int64)

        for (dx, dy), rng in zip(self._dirs, self._sonar):
            if rng <= 0.0:
                continue
            s = np.linspace(self.radius, self.radius + rng, math.ceil(2 * rng * scale) + 2)
            cols = np.clip(to_px(self._x + s * dx), 0, wp - 1)
            rows = np.clip(to_px(self._y + s * dy), 0, hp - 1)
            img[rows, cols] = _COLOURS["beam"]
        # The robot: pixels whose centre lies within radius of the robot's centre.
        yy, xx = np.mgrid[0:hp, 0:wp]
        px = (xx + 0.5) / scale - 0.5
        py = (yy + 0.5) / scale - 0.5
        img[(px - self._x) ** 2 + (py - self._y) ** 2 <= self.radius**2] = _COLOURS["robot"]
        return img


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a number, not {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, not {value!r}") from None
