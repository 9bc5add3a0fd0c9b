"""What the partition figures draw, as data (the drawing itself is :mod:`avq.plotting`).

On a maze (``avq/GridMaze-v0``, ``avq/RobotMaze-v0``) an agent's cells split the free
squares: :func:`partition_view` gives the cell of each square's observation, the greedy
action there, and the squares where each cell's number and arrow go (:func:`cell_anchors`:
always the cell's own squares, one in each of its connected parts). :func:`greedy_walk` follows the greedy policy from one
start and says how it ends: at the goal, bumping into a wall, in a loop; :func:`sample_walks`
picks the walks a figure shows. A
:class:`PartitionRecorder` is a ``learn`` callback that keeps views of the partition as
it learns, for the animation.

Only the free non-goal squares are drawn as parts of cells: the episode ends on the
goal square, so no decision is taken there.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import gymnasium as gym
import numpy as np

from avq.agents.base import BaseAgent, EpisodeRecord
from avq.agents.callbacks import BaseCallback

__all__ = [
    "MazeSquares",
    "maze_squares",
    "PartitionView",
    "partition_view",
    "cell_anchors",
    "GreedyWalk",
    "greedy_walk",
    "sample_walks",
    "PartitionRecorder",
    "has_partition",
]


@dataclass(frozen=True)
class MazeSquares:
    """The free non-goal squares of a maze and the observation at each one's centre.

    Attributes:
        squares: ``(k, 2)`` int ``(x, y)``, row-major (y grows downwards, as in the layout).
        observations: ``(k, n)`` float64, what the agent observes at each square's centre.
    """

    squares: np.ndarray
    observations: np.ndarray


def maze_squares(env: gym.Env) -> MazeSquares:
    """The free non-goal squares of a maze env and its observation at each centre.

    The observations are read by resetting ``env`` at each square, so give an env that is
    not being trained on.
    """
    base = env.unwrapped
    layout = getattr(base, "layout", None)
    if layout is None or not hasattr(layout, "free_positions"):
        raise ValueError("a partition is drawn on a maze (avq/GridMaze-v0 or avq/RobotMaze-v0); this env has no layout")
    squares = layout.free_positions(include_goal=False).astype(np.int64)
    observations = np.stack([base.reset(options={"start": (int(x), int(y))})[0] for x, y in squares])
    return MazeSquares(squares, observations.astype(np.float64))


def has_partition(agent: BaseAgent | type) -> bool:
    """Whether an agent (or agent class) has cells to draw: it answers ``cells(observations)``."""
    return callable(getattr(agent, "cells", None))


@dataclass(frozen=True)
class PartitionView:
    """The partition of a maze's squares into an agent's cells at one moment.

    Attributes:
        episode: The episodes the agent had finished.
        squares: ``(k, 2)`` the free non-goal squares (as :class:`MazeSquares`).
        cells: ``(k,)`` the cell of each square; an agent without cells has one per square.
        actions: ``(k,)`` the greedy action at each square (0 N, 1 E, 2 S, 3 W).
        n_cells: The number of cells (some may hold no square).
        vectors: ``(n_cells, 2)`` the codebook vectors' ``(x, y)``, or None for an agent without a codebook.
        anchors: ``(m, 2)`` rows ``(cell, index in squares)``: the squares where the cells' numbers
            and arrows go (:func:`cell_anchors`; worked out when first asked for).
    """

    episode: int
    squares: np.ndarray
    cells: np.ndarray
    actions: np.ndarray
    n_cells: int
    vectors: np.ndarray | None

    @cached_property
    def anchors(self) -> np.ndarray:
        return cell_anchors(self.squares, self.cells)


def cell_anchors(squares: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Where each cell's number and arrow go: in each connected part of the cell (squares joined
    by a side), the square nearest to the part's mean (the first in row-major order on a tie).

    A cell's codebook vector may lie on another cell's square (squares are sampled at their
    centres), a cell may be cut in two by a wall, and the mean of an L-shaped part may lie
    outside it; the anchors are always squares of the cell itself, one per part.

    Returns:
        ``(m, 2)`` int rows ``(cell, index in squares)``, by cell and then by part.
    """
    squares = np.asarray(squares)
    cells = np.asarray(cells)
    xs, ys, cs = squares[:, 0].tolist(), squares[:, 1].tolist(), cells.tolist()
    at = {(x, y): i for i, (x, y) in enumerate(zip(xs, ys))}
    raster = np.lexsort((squares[:, 0], squares[:, 1])).argsort().tolist()  # each square's place in row-major order
    part = [-1] * len(cs)
    parts: list[
        tuple[int, int, list[int]]
    ] = []  # (cell, first square, squares): one per connected part, found from its first square
    for i in range(len(cs)):  # (a flood fill: faster than labelling the grid once per cell, as it was)
        if part[i] >= 0:
            continue
        part[i] = len(parts)
        own, todo = [], [i]
        while todo:
            j = todo.pop()
            own.append(j)
            x, y = xs[j], ys[j]
            for n in (at.get((x, y - 1)), at.get((x - 1, y)), at.get((x + 1, y)), at.get((x, y + 1))):
                if n is not None and part[n] < 0 and cs[n] == cs[i]:  # 4-connected
                    part[n] = part[i]
                    todo.append(n)
        own.sort(key=raster.__getitem__)  # row-major
        parts.append((cs[i], raster[own[0]], own))
    rows = []
    for c, _, own in sorted(parts, key=lambda p: p[:2]):  # by cell, then by part (its first square, row-major)
        at_own = np.array(own)
        xy = squares[at_own].astype(float)
        rows.append((c, at_own[np.argmin(((xy - xy.mean(axis=0)) ** 2).sum(axis=1))]))
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def partition_view(agent: BaseAgent, maze: MazeSquares) -> PartitionView:
    """The agent's partition of the maze's squares now (see :class:`PartitionView`)."""
    actions, _ = agent.predict(maze.observations, deterministic=True)
    actions = np.asarray(actions, dtype=np.int64).reshape(-1)
    cells_of = getattr(agent, "cells", None)
    if callable(cells_of):  # (has_partition)
        cells = np.asarray(cells_of(maze.observations), dtype=np.int64)
        n_cells = int(agent.n_cells)
    else:
        cells = np.arange(len(maze.squares))
        n_cells = len(cells)
    codebook = getattr(agent, "codebook_", None)
    vectors = None if codebook is None else np.asarray(codebook, dtype=float)[:, :2]
    return PartitionView(int(agent.num_episodes), maze.squares, cells, actions, n_cells, vectors)


@dataclass(frozen=True)
class GreedyWalk:
    """Where the greedy policy goes from one start.

    Attributes:
        positions: ``(n, 2)`` the positions visited, the start first.
        outcome: ``"goal"``; ``"bump"``: the last move ran into a wall, and since the policy and
            the position stay the same it does so forever; ``"loop"``: the walk came back to
            ``positions[loop_from]`` and goes round forever; ``"limit"``: none of these within
            the step limit (on a maze with slip, where a walk is a random sample, the only
            other end than the goal).
        steps: Moves taken (bumps included).
        loop_from: For a loop, the index in ``positions`` where the loop starts.
        bump_action: For a bump, the action that runs into the wall.
    """

    positions: np.ndarray
    outcome: str
    steps: int
    loop_from: int | None = None
    bump_action: int | None = None


def _repeatable(base: Any) -> bool:
    """Whether a maze's greedy walk is determined by the position (no slip, no noisy observation)."""
    dyn = base.dynamics
    if getattr(dyn, "slip", 0.0) > 0.0:
        return False
    return not (getattr(dyn, "observe_sonar", False) and getattr(dyn, "sonar_noise", 0.0) > 0.0)


def greedy_walk(agent: BaseAgent, env: gym.Env, start: tuple[float, float], max_steps: int = 100) -> GreedyWalk:
    """Follow the greedy policy from ``start`` on a maze, up to the goal, a bump, a loop or ``max_steps``.

    The env is reset at ``start`` (give one that is not being trained on). On a deterministic
    maze the greedy policy is a function of the position, so a bump (the robot stays where it
    is) or a position seen before means it never reaches the goal: the walk stops there and
    says so (see :class:`GreedyWalk`).
    """
    base: Any = env.unwrapped  # (a maze: GridMaze, RobotMaze or one with their position and dynamics)
    obs, _ = base.reset(options={"start": start})
    repeatable = _repeatable(base)
    here = tuple(base.position)
    positions = [here]
    seen = {here: 0}
    for step in range(1, int(max_steps) + 1):
        action, _ = agent.predict(obs, deterministic=True)
        obs, _, terminated, _, info = base.step(action)
        here = tuple(base.position)
        if terminated:
            return GreedyWalk(np.array(positions + [here]), "goal", step)
        if repeatable and info.get("collision") and here == positions[-1]:
            return GreedyWalk(np.array(positions), "bump", step, bump_action=int(np.asarray(action).reshape(-1)[0]))
        positions.append(here)
        if repeatable and here in seen:
            return GreedyWalk(np.array(positions), "loop", step, loop_from=seen[here])
        seen.setdefault(here, len(positions) - 1)
    return GreedyWalk(np.array(positions), "limit", int(max_steps))


def sample_walks(agent: BaseAgent, env: gym.Env, max_steps: int = 100) -> list[GreedyWalk]:
    """The greedy walks a partition figure shows: from the start farthest from the goal (in
    shortest-path steps; the first in row-major order on a tie) among those from which the
    greedy policy reaches the goal, and from the farthest among those from which it does not;
    each if there is one. Success is read by :func:`avq.evaluation.evaluate_maze` with the
    same step limit."""
    from avq.evaluation import evaluate_maze

    outcomes = evaluate_maze(agent, env, max_steps=max_steps)["outcomes"]
    walks = []
    for reached in (True, False):
        group = [o for o in outcomes if o["success"] == reached]
        if group:
            farthest = max(group, key=lambda o: o["shortest"])  # max keeps the first of equals
            walks.append(greedy_walk(agent, env, farthest["start"], max_steps=max_steps))
    return walks


class PartitionRecorder(BaseCallback):
    """A ``learn`` callback (:class:`~avq.agents.callbacks.BaseCallback`) that keeps :class:`PartitionView` s of
    the agent as it learns; a compiled loop stops only at the episodes whose views it keeps.

    It keeps the view after the first episode and after every ``every``-th episode, where
    ``every`` starts at 1 and doubles (keeping the views at its new multiples) whenever more
    than ``max_frames`` are kept, so that a run of any length leaves between
    ``max_frames / 2`` and ``max_frames`` evenly spaced views without knowing its length.
    :meth:`views` adds the agent's state at the end. It never stops ``learn``, and learning
    with it gives the same agent as learning without it.

    Args:
        env: A maze env that is not being trained on (its observations at the squares are read once;
            kept as ``env`` for drawing).
        max_frames: Views kept at most, besides the first and the last.
    """

    def __init__(self, env: gym.Env, max_frames: int = 100) -> None:
        if int(max_frames) < 2:
            raise ValueError(f"max_frames must be >= 2, not {max_frames!r}")
        self.env = env
        self.maze = maze_squares(env)
        self.max_frames = int(max_frames)
        self.every = 1
        self._first: PartitionView | None = None
        self._kept: list[PartitionView] = []
        self._agent: BaseAgent | None = None

    def episodes_to_next_call(self, agent: BaseAgent) -> int:
        """The first episode, then every ``every``-th: only there does a compiled loop need to stop."""
        return 1 if self._first is None else self.every - agent.num_episodes % self.every

    def on_episode_end(self, agent: BaseAgent, record: EpisodeRecord) -> None:
        self._agent = agent
        episode = int(record["episode"])
        if self._first is None:
            self._first = partition_view(agent, self.maze)
        elif episode % self.every == 0:
            self._kept.append(partition_view(agent, self.maze))
            if len(self._kept) > self.max_frames:
                self.every *= 2
                self._kept = [v for v in self._kept if v.episode % self.every == 0]

    def __call__(self, agent: BaseAgent, record: EpisodeRecord) -> None:
        """The recorder as a plain function ``callback(agent, record)`` (then ``learn`` stops after every
        episode; passed as itself, it stops only where a view is kept)."""
        self.on_episode_end(agent, record)

    def learn(self, agent: BaseAgent, total_episodes: int) -> BaseAgent:
        """``agent.learn(total_episodes=total_episodes, callback=self)``. Returns the agent."""
        return agent.learn(total_episodes=int(total_episodes), callback=self)

    def views(self) -> list[PartitionView]:
        """The views kept, in order, ending with the agent as it is now."""
        views = ([self._first] if self._first is not None else []) + self._kept
        if self._agent is not None and (not views or views[-1].episode != self._agent.num_episodes):
            views.append(partition_view(self._agent, self.maze))
        return views
