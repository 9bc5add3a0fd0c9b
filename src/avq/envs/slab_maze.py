"""A point in the unit cube of ``d`` dimensions moving through walls with openings: the robot's maze generalised
to ``d`` from 2 to 8, a family of tasks of growing dimension.

:class:`SlabMaze` keeps the state, checks its arguments and answers the Gymnasium API; what a slab is, a
move, a maze drawn from a seed and the check that a maze leads to its goal live in
:mod:`avq.envs.slab_geometry`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import check_choice, check_int, check_optional, check_range
from avq.envs.slab_geometry import (
    EPS,
    Slabs,
    draw_slabs,
    lattice_distances,
    parse_slabs,
    regions_reaching_goal,
    slab_move,
    unreachable_message,
)

__all__ = ["SlabMaze"]

#: The dimensions a SlabMaze may have.
MIN_DIMS, MAX_DIMS = 2, 8
#: Cells a side of the ``ansi`` picture at most.
MAX_PICTURE = 40
#: The most points of a lattice of moves that :meth:`SlabMaze.lattice_distances` searches (about 32 MB).
MAX_LATTICE = 2_000_000


class SlabMaze(gym.Env[np.ndarray, np.int64]):
    """A point moves through a ``d``-dimensional maze of walls with openings towards a goal corner.

    ## Description
    The space is the unit cube ``[0, 1]^d``, ``d = dims`` from 2 to 8. The walls are *slabs*: a slab is a
    wall of no thickness perpendicular to one axis at some ``position`` on it, spanning the whole cube
    except its opening, an axis-aligned box: the points of the slab's plane with
    ``low[k] <= x[k] <= high[k]`` on every other axis ``k``. A slab separates the points with
    ``x[axis] < position`` from those with ``x[axis] >= position``. Slabs on one axis cut the cube into
    slices; all slabs together cut it into box-shaped regions. The goal is the closed cube of side
    ``goal_size`` in the corner ``(1, ..., 1)``; the fixed start is near the opposite corner.

    ## Actions
    ``Discrete(2 * d)``: action ``2 * k`` moves ``+move`` along axis ``k``, action ``2 * k + 1`` moves
    ``-move`` along it.

    ## Observations
    ``Box(float32, (d,))``: the point ``x``, bounds 0 and 1 on every axis.

    ## Rewards
    A move that would leave the cube, or cross a slab (change side of its plane) where the point's other
    coordinates, which a move does not change, are outside the slab's opening, is a collision: -10, the
    point **stays where it was**, ``info["collision"]`` True. Only the move's crossing of the slab's plane
    matters; a point on a plane (reached through its opening) is on its high side. Any other move: -1, or
    +10 when every coordinate of the new point is at least ``1 - goal_size``.

    ## Episode end
    Terminates in the goal. The env truncates by itself after ``max_steps`` steps, default
    ``ceil(10 * d / move)`` (200 for ``d = 2`` at the default move, 800 for ``d = 8``): ten times the
    ``d / move`` moves of a run from corner to corner without walls. ``avq/SlabMaze-v0`` is registered
    without ``max_episode_steps``, as RobotMaze is.

    ## Arguments
    - ``dims``: the dimension ``d``, an integer from 2 to 8.
    - ``walls``: None (``d`` slabs, one per axis), a number of slabs drawn from ``layout_seed``, or a
      list of slabs ``(axis, position, low, high)``, ``low`` and ``high`` the opening's corners (``d``
      numbers each in [0, 1]; the entries on the slab's own axis are ignored), to state a maze. Positions
      lie in ``[move, 1 - goal_size]``, slabs on one axis at least ``move`` apart (so that every slice is at
      least one move thick and no move crosses two slabs). The maze must lead to the goal: from every
      region with ``start="random"``, from the start's with ``"fixed"`` (see :attr:`slabs` for the check).
    - ``layout_seed``: the seed of drawn slabs. Slab ``j`` is perpendicular to axis ``j % d``; the slabs of an
      axis lie in equal bins of ``[move, 1 - goal_size]``, each at a uniform place. The axes are put in a
      random order, in which a path passes their slabs: an opening is ``opening`` wide on every other axis,
      at a uniform place where it overlaps (by at least a move) the last slice of each axis passed before
      it and every slice of each axis passed after it (wider than ``opening`` where it must span several
      slabs). So every region leads to the goal, whatever the draw. ``opening`` in ``[move, 1]`` (default
      0.5): the open part of a slab with one slab per axis is ``opening^(d - 1)``, 1/128 at ``d = 8``.
    - ``move`` in (0, 0.5] (default 0.1); ``goal_size`` in ``[move, 0.5]`` (default 0.1).
    - ``start``: ``"random"``: uniform in the cube outside the goal (from ``self.np_random``); ``"fixed"``:
      ``(move / 2, ..., move / 2)``. ``reset(options={"start": x})`` starts at any point ``x`` of the cube
      outside the goal.
    - ``slip`` in [0, 1): with this probability a move goes along one of the other axes instead, each of the
      ``2 * (d - 1)`` moves along them equally likely (never backwards), drawn from ``self.np_random``; 0:
      deterministic, and ``step`` draws nothing.
    - ``max_steps``: None (the default above) or an integer >= 1. ``render_mode``: ``"ansi"``.

    ## Info
    ``collision`` (bool).

    ## Size
    :attr:`full_resolution_states` is ``ceil(1 / move)^d``, the points of a grid with one point per move on
    every axis: at the default move, 100 for ``d = 2``, 10^3, 10^4, 10^6 and 10^8 for ``d = 3, 4, 6, 8``.
    :meth:`start_positions` draws evaluation starts with a seed of their own. :meth:`shortest_steps` and
    :meth:`lattice_distances` search the lattice of moves through a start, up to :data:`MAX_LATTICE` points
    (``d = 6`` at the default move; ``d = 8`` has 10^8).
    """

    metadata = {"render_modes": ["ansi"], "render_fps": 8}

    def __init__(
        self,
        dims: int = 2,
        walls: int | Sequence[Any] | None = None,
        layout_seed: int = 0,
        opening: float = 0.5,
        move: float = 0.1,
        goal_size: float = 0.1,
        start: str = "random",
        slip: float = 0.0,
        max_steps: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        if isinstance(dims, bool) or not isinstance(dims, (int, np.integer)) or not MIN_DIMS <= dims <= MAX_DIMS:
            raise ValueError(f"dims must be an integer from {MIN_DIMS} to {MAX_DIMS} (the cube's axes), not {dims!r}")
        self.dims = d = int(dims)
        self.move = check_range("move", move, 0.0, 0.5, low_open=True)
        self.goal_size = _at_least_a_move(
            "goal_size", goal_size, self.move, 0.5, "every lattice of moves meets the goal"
        )
        self.opening = _at_least_a_move("opening", opening, self.move, 1.0, "every lattice of moves passes an opening")
        self.slip = check_range("slip", slip, 0.0, 1.0, high_open=True)
        self.layout_seed = check_int("layout_seed", layout_seed, 0)
        self.start = check_choice("start", start, ("random", "fixed"))
        self.max_steps = check_optional(check_int, "max_steps", max_steps, 1) or math.ceil(10 * d / self.move - EPS)
        if render_mode not in (None, "ansi"):
            raise ValueError(f"render_mode must be None or 'ansi', not {render_mode!r}")
        self.render_mode = render_mode
        self.full_resolution_states: int = math.ceil(1.0 / self.move - EPS) ** d
        """Points of a grid with one point per ``move`` on every axis: ``ceil(1 / move)^d``."""

        if walls is None or (isinstance(walls, (int, np.integer)) and not isinstance(walls, bool)):
            n = d if walls is None else check_int("walls", walls, 0)
            self._slabs = draw_slabs(n, d, self.opening, self.move, self.goal_size, self.layout_seed)
        elif isinstance(walls, Sequence) and not isinstance(walls, str):
            self._slabs = parse_slabs(walls, d, self.move, self.goal_size)
            reached = regions_reaching_goal(self._slabs, d, self.move)
            needed = reached if self.start == "random" else reached[(0,) * d]
            if not needed.all():
                shown = reached if self.start == "random" else np.zeros_like(reached)
                raise ValueError(f"start={self.start!r}: " + unreachable_message(self._slabs, d, shown, self.move))
        else:
            raise ValueError(f"walls must be None, a number of slabs or a list of slabs, not {walls!r}")

        self.observation_space = spaces.Box(0.0, 1.0, shape=(d,), dtype=np.float32)
        self.action_space = spaces.Discrete(2 * d)
        self._goal_low = 1.0 - self.goal_size
        self._pos = np.zeros(d, dtype=np.float64)
        self._steps = 0

    # -- Gymnasium API -------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: at ``options["start"]``, a point of the cube outside the goal, when given; else as
        ``start`` says. A ``seed`` seeds ``self.np_random`` first (Gymnasium's rule). Returns the observation and
        the info."""
        super().reset(seed=seed)
        given = None if options is None else options.get("start")
        if given is not None:
            self._pos[:] = self._checked_start(given)
        elif self.start == "fixed":
            self._pos[:] = self._fixed_start()
        else:
            self._pos[:] = self._random_points(self.np_random, 1)[0]
        self._steps = 0
        return self._pos.astype(np.float32), {"collision": False}

    def step(self, action: int | np.integer) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Move ``move`` along axis ``action // 2``, up for an even action, down for an odd one (along another
        axis with probability ``slip``), unless the move collides.

        Returns ``(observation, reward, terminated, truncated, info)`` as the class describes; ``truncated``
        after ``max_steps`` steps.
        """
        if isinstance(action, bool) or not isinstance(action, (int, np.integer)) or not 0 <= action < 2 * self.dims:
            raise ValueError(f"action must be an integer in [0, {2 * self.dims - 1}], not {action!r}")
        a = int(action)
        if self.slip > 0.0 and self.np_random.random() < self.slip:
            other = int(self.np_random.integers(2 * self.dims - 2))  # (a move along another axis: skip a's two)
            a = other + 2 if other >= a - a % 2 else other
        reward, terminated, collision = slab_move(
            self._pos, a >> 1, -self.move if a & 1 else self.move, self._slabs, self._goal_low
        )
        self._steps += 1
        return self._pos.astype(np.float32), reward, terminated, self._steps >= self.max_steps, {"collision": collision}

    def render(self) -> str | None:
        """With ``render_mode="ansi"``, the slice through the point along axes 0 (across) and 1 (up) as text:
        ``R`` the point, ``|`` and ``-`` the closed parts of slabs of axes 0 and 1 there, ``G`` the goal's
        square on those axes, one character a move (at most 40 a side); for ``d > 2`` a last line gives the
        other coordinates. Else None."""
        if self.render_mode != "ansi":
            return None
        n = min(math.ceil(1.0 / self.move - EPS), MAX_PICTURE)
        centres = (np.arange(n) + 0.5) / n
        picture = np.full((n, n), ".")
        goal = centres >= self._goal_low
        picture[np.ix_(goal, goal)] = "G"
        s, x = self._slabs, self._pos
        for a, c, low, high in zip(s.axis, s.position, s.low, s.high):
            if a > 1:
                continue
            other = np.delete(np.arange(self.dims), [0, 1])
            if np.any(x[other] < low[other]) or np.any(x[other] > high[other]):
                shut = np.ones(n, dtype=np.bool_)
            else:
                shut = (centres < low[1 - a]) | (centres > high[1 - a])
            line = min(int(c * n), n - 1)
            if a == 0:
                picture[shut, line] = "|"
            else:
                picture[line, shut] = "-"
        picture[min(int(x[1] * n), n - 1), min(int(x[0] * n), n - 1)] = "R"
        text = "\n".join("".join(row) for row in picture[::-1]) + "\n"
        if self.dims > 2:
            text += "x[2:] = (" + ", ".join(f"{v:.3f}" for v in x[2:]) + ")\n"
        return text

    # -- the maze ----------------------------------------------------------------------
    @property
    def slabs(self) -> list[tuple[int, float, tuple[float, ...], tuple[float, ...]]]:
        """The maze's slabs ``(axis, position, low, high)``, sorted by axis and position, as ``walls=`` takes them
        (``SlabMaze(dims, walls=env.slabs, ...)`` states the same maze).

        A drawn maze, and a stated one with ``start="random"``, leads to the goal from every region; the
        check searches the regions, counting a passage through a slab where its opening overlaps the face
        between the two regions by at least ``move`` on every other axis (wide enough for every lattice of
        moves). It is exact in what it accepts and cautious otherwise: a maze connected only through
        narrower gaps is refused.
        """
        return self._slabs.specs()

    @property
    def slab_arrays(self) -> Slabs:
        """The slabs as arrays (a :class:`~avq.envs.slab_geometry.Slabs`), as the compiled move reads them."""
        return self._slabs

    @property
    def position(self) -> np.ndarray:
        """The point (a float64 copy)."""
        return self._pos.copy()

    @property
    def elapsed_steps(self) -> int:
        """Steps taken in the current episode (the maze truncates at ``max_steps``)."""
        return self._steps

    def start_positions(self, n: int = 100, seed: int = 0) -> np.ndarray:
        """``n`` evaluation starts, ``(n, d)`` float64, uniform in the cube outside the goal, drawn from ``seed``
        (not from ``self.np_random``): the same points for every agent. Start there with
        ``reset(options={"start": point})``."""
        return self._random_points(np.random.default_rng(check_int("seed", seed, 0)), check_int("n", n, 0))

    def goal_distance(self, points: Any) -> np.ndarray | float:
        """How far each point is from the goal in moves, walls aside: the sum over the axes of how far the point is
        below the goal's lower face, over ``move``, each axis rounded to a millionth of a move. ``points``: one point
        ``(d,)`` (a float back) or ``(n, d)`` (``n`` floats back). 0 in the goal; never more than the moves a walk
        needs, so ``-goal_distance`` is a potential that tells an agent where the goal is
        (:class:`~avq.envs.PotentialShaping`). With the default move (0.1) the rounding makes every move on the
        lattice of whole moves through a start such as the fixed one change it by exactly one move (or none, or half
        of one across the goal's face) from the float32 observations too, so that shaped rewards keep the ties an
        explorer's planned values have without it, where rounding noise would break them at random
        (docs/results/dimensions.md#shaped).

        Raises:
            ValueError: ``points`` is not ``d`` numbers or rows of ``d`` numbers.
        """
        try:
            x = np.asarray(points, dtype=np.float64)
        except (TypeError, ValueError):
            x = np.empty(0)
        if x.ndim not in (1, 2) or x.shape[-1] != self.dims:
            raise ValueError(
                f"points must be {self.dims} numbers or an (n, {self.dims}) array of them, not {points!r}; "
                "give one point of the cube or rows of points"
            )
        moves = np.round(np.maximum(0.0, self._goal_low - x) / self.move, 6).sum(axis=-1)
        return float(moves) if x.ndim == 1 else moves

    def lattice_distances(self, start: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Least moves from ``start`` to every point of the lattice of moves through it, slip aside.

        ``start``: a point of the cube outside the goal; None, the fixed start ``(move / 2, ..., move / 2)``.
        Returns ``(distances, points)``: ``distances`` an int64 array with one axis per dimension, and ``points`` the
        lattice's coordinates on each axis, a ``(d,)`` object array of float64 arrays: ``distances[i, j, ...]`` is
        the point ``(points[0][i], points[1][j], ...)``. A breadth-first search whose moves collide where
        :meth:`step`'s would and whose walks end in the goal, as episodes do; -1 where no walk from ``start`` gets
        (walls; a point of the goal reached only through the goal). The lattice's points are ``start`` plus whole
        moves, inside the cube. Its coordinates and :meth:`step`'s positions are sums of moves rounded differently,
        so where a point lies within rounding of the goal's edge or of a slab's plane (a start on the lattice of
        ``move`` itself, such as ``(0, 0)``) the two can disagree; from the starts that :meth:`reset` draws they
        agree.

        Raises:
            ValueError: for a start outside the cube or in the goal, or a lattice of more than
                :data:`MAX_LATTICE` points.
        """
        dist, points, _ = self._lattice(start)
        return dist, points

    def shortest_steps(self, start: Any = None) -> int:
        """The least number of moves from ``start`` (None: the fixed start) to the goal, slip aside; -1 if the walls
        leave no path. From :meth:`lattice_distances`, whose errors it raises."""
        dist, _, goal = self._lattice(start)
        reached = dist[goal & (dist >= 0)]
        return int(reached.min()) if reached.size else -1

    def _lattice(self, start: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`lattice_distances`' ``(distances, points)`` and which points are in the goal."""
        x = self._fixed_start() if start is None else self._checked_start(start)
        m = self.move
        below = np.floor(x / m + EPS).astype(np.int64)
        below -= x - below * m < 0.0  # (no point below the cube's face by rounding)
        above = np.floor((1.0 - x) / m + EPS).astype(np.int64)
        origin = x - below * m
        above -= origin + (below + above) * m > 1.0  # (nor above it)
        counts = below + above + 1
        size = int(np.prod(counts.astype(object)))
        if size > MAX_LATTICE:
            raise ValueError(
                f"the lattice of moves through this start has {size:,} points (move={m}, dims={self.dims}), "
                f"more than the {MAX_LATTICE:,} searched; use a larger move or fewer dims"
            )
        source = int(np.ravel_multi_index(tuple(below), tuple(counts)))
        dist, goal = lattice_distances(origin, counts, source, m, self._slabs, self._goal_low)
        points = np.empty(self.dims, dtype=object)
        points[:] = [origin[k] + m * np.arange(counts[k]) for k in range(self.dims)]
        return dist.reshape(tuple(counts)), points, goal.reshape(tuple(counts))

    def _fixed_start(self) -> np.ndarray:
        """The fixed start, ``(move / 2, ..., move / 2)``."""
        return np.full(self.dims, self.move / 2)

    def _random_points(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` points uniform in the cube outside the goal (drawn again while in the goal)."""
        points = rng.random((n, self.dims))
        while (inside := np.all(points >= self._goal_low, axis=1)).any():
            points[inside] = rng.random((int(inside.sum()), self.dims))
        return points

    def _checked_start(self, start: Any) -> np.ndarray:
        try:
            x = np.array(start, dtype=np.float64).reshape(self.dims)
        except (TypeError, ValueError):
            raise ValueError(
                f"options['start'] must be {self.dims} numbers (a point of the cube), not {start!r}"
            ) from None
        if not (np.all(x >= 0.0) and np.all(x <= 1.0)):
            raise ValueError(f"options['start']={tuple(x)} is outside the cube [0, 1]^{self.dims}")
        if np.all(x >= self._goal_low):
            raise ValueError(f"options['start']={tuple(x)} is in the goal; choose a point outside it")
        return x


def _at_least_a_move(name: str, value: Any, move: float, high: float, why: str) -> float:
    """``value`` as a float if it is a number in ``[move, high]``; else a ``ValueError`` that says why."""
    try:
        return check_range(name, value, move, high)
    except ValueError:
        raise ValueError(
            f"{name} must be in [move, {high}] = [{move}, {high}] (at least one move, so that {why}), not {value!r}"
        ) from None
