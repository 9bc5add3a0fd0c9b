"""The robot maze's geometry, compiled: moves, collisions, sonar ranges, random starts (docs/explanation/paper.md#the-maze).

:class:`~avq.envs.robot_maze.RobotMaze` keeps the state and calls these functions; avq's
compiled loops (fused training, the greedy walks of :func:`avq.evaluate_maze`) call the same
ones on the arrays of a :class:`RobotDynamics`, so that the env and a loop cannot drift apart.
They are small module-level functions over plain NumPy arrays and floats (``disc_collides``,
``in_goal``, ``cast_ray``, ``sonar_ranges``, ``robot_move``, ``random_start``,
``lattice_distances``), written so that Numba can compile them as they are; they live apart
from the env so that a reader of either finds one subject in its file.

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

import numpy as np
from numba import njit

from avq.envs.grid_maze import BUMP_REWARD, GOAL_REWARD, MOVE_REWARD

__all__ = [
    "RobotDynamics",
    "robot_move",
    "random_start",
    "sonar_ranges",
    "sonar_directions",
    "padded_walls",
    "disc_collides",
    "in_goal",
    "cast_ray",
    "lattice_distances",
    "N_SONARS",
    "EPS",
]

#: Number of sonar beams (the Sensus 300 ring of the Nomad 200, docs/explanation/paper.md#the-maze).
N_SONARS = 16

#: Rounding tolerance of every geometric comparison (touching, goal square).
#: Positions are sums of moves, so "exactly touching" may be off by a few ulps.
EPS = 1e-9


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


# -- the frozen description that a compiled loop runs -----------------------------


@dataclass(frozen=True)
class RobotDynamics:
    """Everything a compiled loop needs to run a :class:`~avq.envs.robot_maze.RobotMaze` exactly as ``step``
    and ``reset`` do.

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
