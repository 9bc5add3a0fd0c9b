"""The shared driver of fused training: a built-in maze's dynamics and an agent's rules in one compiled loop.

:func:`plan` decides whether an environment can be fused: a ``GridMaze``, or a ``RobotMaze``
with noise-free sonar, under Gymnasium's standard wrappers (:func:`avq.envs.compiled.compiled_maze`).
Each agent family writes its own loop (``avq_sarsa/fused.py``, ``plan/fused.py``,
``baselines/fused.py``); they read the maze only through its public, frozen description
(:class:`~avq.envs.grid_maze.GridDynamics`, :class:`~avq.envs.robot_geometry.RobotDynamics`), the
arguments :func:`maze_arguments` makes of it, and step it with :func:`maze_start`,
:func:`maze_move` and :func:`maze_observation` here. They call the very kernels of the generic
path, draw from the same generators in the same order (the agent's for its decisions, the
environment's ``np_random`` for start positions) and apply the same step limit, so that with the
same seed both paths give identical results.

A loop runs until a budget of steps or episodes is spent and returns ``(steps, episodes,
status)``, writing one record row per finished episode (columns ``R_*``); :func:`drive` calls it,
grows the agent's arrays when asked, and hands the episode back to the environment object
(position and elapsed steps), so that stepping it from Python goes on from there.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

from avq._numba import borrowed
from avq._random import below
from avq.envs.compiled import CompiledMaze, compiled_maze
from avq.envs.grid_maze import GridDynamics, grid_move, slipped
from avq.envs.robot_geometry import random_start, robot_move, sonar_ranges

__all__ = [
    "Maze",
    "plan",
    "maze_arguments",
    "maze_types",
    "borrowed_maze",
    "borrowed_grid_maze",
    "NearestCache",
    "nearest_cache",
    "cached_nearest",
    "drive",
    "budget_left",
    "grid_rows",
    "add_grid_rows",
    "maze_start",
    "maze_move",
    "maze_observation",
    "DONE",
    "NEED_CAPACITY",
    "RECORDS_FULL",
    "GO_ON",
    "N_R",
]

# Records written by the fused loops, one row per episode.
R_STEPS, R_RETURN, R_CELLS, R_APPENDS, R_MERGES, R_REFUSED, R_DECISIONS = range(7)
N_R = 7
# Status returned by the fused loops (and GO_ON, by budget_left: a new episode may start).
DONE, NEED_CAPACITY, RECORDS_FULL = 0, 1, 2
GO_ON = -1


def plan(env, grid_only: bool = False) -> CompiledMaze | None:
    """The maze a fused loop can run for ``env``, or None (step the environment from Python).

    Fused: a ``GridMaze``, or (unless ``grid_only``) a ``RobotMaze`` with noise-free sonar, under
    Gymnasium's standard wrappers only; any other wrapper may change what a step does.
    """
    maze = compiled_maze(env)
    if maze is None:
        return None
    if isinstance(maze.dynamics, GridDynamics):
        return maze
    if grid_only or maze.dynamics.sonar_noise != 0.0:
        return None
    return maze


class Maze(NamedTuple):
    """A built-in maze as a fused loop reads it (one record, which Numba takes as it is)."""

    #: RobotMaze (continuous moves, ``walls`` its occupancy grid) or GridMaze (``walls`` its squares).
    robot: bool
    walls: np.ndarray
    #: The goal.
    gx: float
    gy: float
    starts: np.ndarray
    #: The fixed start, or NaN for random starts.
    fixed: np.ndarray
    #: RobotMaze's move length and radius; GridMaze's slip probability.
    move: float
    radius: float
    slip: float
    #: RobotMaze's sonar: directions, range, whether observed.
    dirs: np.ndarray
    sonar_range: float
    observe_sonar: bool
    max_episode_steps: int


def maze_arguments(maze: CompiledMaze) -> Maze:
    """The :class:`Maze` record of a compiled maze, for a fused loop."""
    d = maze.dynamics
    fixed = np.array(d.fixed_start if d.fixed_start is not None else (np.nan, np.nan), dtype=np.float64)
    if isinstance(d, GridDynamics):  # (moves of one square, no radius, no sonar)
        robot, walls, move, radius, slip = False, d.walls, 1.0, 0.0, float(d.slip)
        dirs, sonar_range, observe_sonar = np.zeros((0, 2)), 0.0, False
    else:
        robot, walls, move, radius, slip = True, d.grid, float(d.move), float(d.radius), 0.0
        dirs, sonar_range, observe_sonar = d.sonar_directions, float(d.sonar_range), bool(d.observe_sonar)
    gx, gy = float(d.goal[0]), float(d.goal[1])
    steps = int(maze.max_episode_steps)
    return Maze(robot, walls, gx, gy, d.starts, fixed, move, radius, slip, dirs, sonar_range, observe_sonar, steps)


def maze_types(mz: Maze) -> tuple:
    """What Numba's type of ``mz`` depends on, cheaply (its fields' Python types, and its arrays' dtypes,
    dimensions and layout): a key under which an agent keeps the compiled loop it calls directly."""
    return tuple((type(v), v.dtype, v.ndim, v.flags.c_contiguous) if isinstance(v, np.ndarray) else type(v) for v in mz)


@njit(cache=True, inline="always")
def _borrowed(mz: Maze, robot: bool) -> Maze:
    # (Numba's annotation of an @intrinsic's call keeps the typing context, which compiled callers do not pass)
    return Maze(
        robot,
        borrowed(mz.walls),
        mz.gx,
        mz.gy,
        borrowed(mz.starts),
        borrowed(mz.fixed),
        mz.move,
        mz.radius,
        mz.slip,
        borrowed(mz.dirs),
        mz.sonar_range,
        mz.observe_sonar,
        mz.max_episode_steps,
    )


@njit(cache=True, inline="always")
def borrowed_maze(mz: Maze) -> Maze:
    """``mz`` with its arrays as borrowed views (:func:`avq._numba.borrowed`), for the loop's own use."""
    return _borrowed(mz, mz.robot)


@njit(cache=True, inline="always")
def borrowed_grid_maze(mz: Maze) -> Maze:
    """:func:`borrowed_maze` for a loop that runs GridMaze only: ``robot`` is the constant False there, so that
    the compiler drops RobotMaze's branches (its inlined moves and starts) from the loop, as it did when the
    maze's fields were separate arguments."""
    return _borrowed(mz, False)


class NearestCache(NamedTuple):
    """A grid loop's memory of the nearest vector of each square (the nearest is searched once per square
    while the codebook does not change, not at every step)."""

    #: ``(h, w)`` the nearest vector of each square, -1 where not known.
    cell: np.ndarray
    #: ``(h, w)`` its squared scaled distance.
    d2: np.ndarray
    #: ``(2,)`` the geometry version (the agent's count of codebook changes) and the codebook's size that they
    #: hold for.
    seen: np.ndarray


@njit(cache=True, inline="always")
def nearest_cache(mz: Maze) -> NearestCache:
    """An empty :class:`NearestCache` for the maze ``mz`` (one square on RobotMaze, which does not use it)."""
    shape = (1, 1) if mz.robot else mz.walls.shape
    return NearestCache(np.full(shape, -1, dtype=np.int64), np.zeros(shape), np.full(2, -1, dtype=np.int64))


@njit(cache=True, inline="always")
def cached_nearest(cell, d2, seen, V, size: int, geom: int, x, inv_scale, pos) -> tuple[int, float]:
    """:func:`~avq.quantizer.nearest_index` of the grid observation ``x`` (at square ``pos``) among the first
    ``size`` vectors of ``V``, ``(index, squared distance)``, through a :class:`NearestCache` (its arrays
    ``cell``, ``d2``, ``seen``: written here, so taken one by one). When the geometry version ``geom`` has
    changed, the cache is emptied, unless the one change was an append (the version and the size each one
    more), which only the new vector may win, as :func:`~avq.quantizer.nearest_index` would find it.
    (GridMaze's observations have two dimensions: :func:`_grid_d2` writes that search's sum out for them.)"""
    if seen[0] != geom:
        if seen[0] + 1 == geom and seen[1] + 1 == size:
            _nearest_appended(cell, d2, V, size - 1, inv_scale)
        else:
            for k in range(cell.shape[0]):
                for q in range(cell.shape[1]):
                    cell[k, q] = -1
        seen[0] = geom
        seen[1] = size
    iy, ix = int(pos[1]), int(pos[0])
    if cell[iy, ix] < 0:
        cell[iy, ix], d2[iy, ix] = _grid_nearest(V, size, x[0], x[1], inv_scale)
    return cell[iy, ix], d2[iy, ix]


@njit(cache=True, inline="always")
def _grid_d2(V, k: int, gx: float, gy: float, inv_scale) -> float:
    """The squared scaled distance of vector ``k`` (2-D) to ``(gx, gy)``, summed as
    :func:`~avq.quantizer.nearest_index` sums it (from 0.0, dimension by dimension), so to the same bits."""
    zx = (V[k, 0] - gx) * inv_scale[0]
    s = 0.0 + zx * zx
    zy = (V[k, 1] - gy) * inv_scale[1]
    return s + zy * zy


@njit(cache=True)
def _grid_nearest(V, size: int, gx: float, gy: float, inv_scale) -> tuple[int, float]:
    """:func:`~avq.quantizer.nearest_index` of the 2-D observation ``(gx, gy)``: the same answer, lowest index
    on ties."""
    best = 0
    best_d2 = np.inf
    for k in range(size):
        s = _grid_d2(V, k, gx, gy, inv_scale)
        if s < best_d2:
            best_d2 = s
            best = k
    return best, best_d2


@njit(cache=True)
def _nearest_appended(cell, d2, V, c: int, inv_scale) -> None:
    """Vector ``c``, just appended (the last), into a grid's :class:`NearestCache`: it becomes the nearest of
    each known square ``(x, y)`` strictly nearer to it, ties going to the lower index, with the very arithmetic
    of :func:`~avq.quantizer.nearest_index`."""
    for k in range(cell.shape[0]):
        for q in range(cell.shape[1]):
            if cell[k, q] < 0:
                continue
            s = _grid_d2(V, c, float(q), float(k), inv_scale)
            if s < d2[k, q]:
                cell[k, q] = c
                d2[k, q] = s


def drive(
    maze: CompiledMaze,
    mz: Maze,
    loop: Callable,
    state: Callable[[], tuple],
    grow: Callable[[], None],
    max_steps: int,
    max_episodes: int,
    max_records: int,
) -> tuple[int, np.ndarray]:
    """Run a fused loop from the environment's current episode until a budget is spent; returns
    ``(steps, records)`` and leaves the environment where the loop stopped.

    The loop is called as ``loop(*state(), env_rng, maze, pos, budget_steps, budget_episodes, rec)``:
    ``mz`` is the maze's record (:func:`maze_arguments`); ``state()`` gives the agent's leading arguments (its
    records and generator), read again after each ``grow()``, which makes room when the loop returns
    ``NEED_CAPACITY``."""
    pos = np.array(maze.episode_state(), dtype=np.float64)  # x, y, steps elapsed in the episode
    rec = np.zeros((min(max_episodes, max_records), N_R))
    steps = episodes = 0
    while True:
        n, eps, status = loop(
            *state(), maze.np_random, mz, pos, int(max_steps - steps), int(len(rec) - episodes), rec[episodes:]
        )
        steps += n
        episodes += eps
        if status != NEED_CAPACITY:
            break
        grow()
    maze.set_episode_state(pos[0], pos[1], int(pos[2]))
    return steps, rec[:episodes]


def grid_rows(index: dict[tuple[float, float], int], shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """A table's rows keyed by grid square, as a fused grid loop reads them: ``row_of[y, x]`` (-1: no row
    yet) and ``keys[row] = (x, y)``, from the table's index of ``(x, y)`` observations."""
    h, w = shape
    row_of = np.full((h, w), -1, dtype=np.int64)
    keys = np.zeros((h * w, 2), dtype=np.int64)
    for key, row in index.items():
        row_of[int(key[1]), int(key[0])] = row
        keys[row] = int(key[0]), int(key[1])
    return row_of, keys


def add_grid_rows(index: dict[tuple[float, float], int], order: list, keys: np.ndarray, first: int, end: int) -> None:
    """The rows ``first..end-1`` that a fused grid loop added to ``keys``, added to the table's index and to
    its list of keys in order of creation."""
    for row in range(first, end):
        key = (float(keys[row, 0]), float(keys[row, 1]))
        index[key] = row
        order.append(key)


@njit(cache=True, inline="always")
def budget_left(steps: int, episodes: int, budget_steps: int, budget_episodes: int, rec) -> int:
    """Whether a fused loop may start a new episode: ``DONE`` when its budget of steps or episodes is spent,
    ``RECORDS_FULL`` when ``rec`` has no row left for it, else ``GO_ON``."""
    if steps >= budget_steps or episodes >= budget_episodes:
        return DONE
    if episodes >= rec.shape[0]:
        return RECORDS_FULL
    return GO_ON


@njit(cache=True, inline="always")
def maze_start(env_rng, pos, mz) -> None:
    """A new episode's start, drawn as the maze's ``reset`` draws it."""
    if mz.fixed[0] == mz.fixed[0]:  # not NaN: a mz.fixed start
        pos[0] = mz.fixed[0]
        pos[1] = mz.fixed[1]
    elif mz.robot:
        pos[0], pos[1] = random_start(env_rng, mz.starts, mz.walls, mz.radius, mz.gx, mz.gy)
    else:
        k = below(env_rng, mz.starts.shape[0])  # (env_rng.integers(0, n), without allocating)
        pos[0] = mz.starts[k, 0]
        pos[1] = mz.starts[k, 1]
    pos[2] = 0.0


@njit(cache=True, inline="always")
def maze_move(env_rng, pos, a, mz):
    """One step of the maze from ``pos`` (in place): ``(reward, terminated, collision)``. GridMaze's
    moves mz.slip as its ``step`` makes them mz.slip (from the maze's generator)."""
    if mz.robot:
        pos[0], pos[1], r, terminated, collision = robot_move(
            mz.walls, pos[0], pos[1], a, mz.move, mz.radius, mz.gx, mz.gy
        )
    else:
        a = slipped(env_rng, a, mz.slip)
        nx, ny, r, terminated, collision = grid_move(mz.walls, int(pos[0]), int(pos[1]), a, int(mz.gx), int(mz.gy))
        pos[0] = nx
        pos[1] = ny
    pos[2] += 1.0
    return r, terminated, collision


@njit(cache=True, inline="always")
def maze_observation(x, pos, mz, sonar) -> None:
    """The observation at ``pos`` as the agent sees it: GridMaze's integer ``(x, y)``; RobotMaze's
    float32 values (and sonar ranges), as float64."""
    if not mz.robot:
        x[0] = pos[0]
        x[1] = pos[1]
        return
    x[0] = np.float64(np.float32(pos[0]))
    x[1] = np.float64(np.float32(pos[1]))
    if mz.observe_sonar:
        sonar_ranges(mz.walls, pos[0], pos[1], mz.radius, mz.dirs, mz.sonar_range, sonar)
        for k in range(sonar.shape[0]):
            x[2 + k] = np.float64(np.float32(sonar[k]))
