"""What a policy picture draws, as data: an agent's greedy action and cell at every pixel of a plane through
its observation space (the drawing is :mod:`avq.plotting.policy`).

Two views of a ``Box`` observation space of any dimension, over two chosen dimensions ``dims``:

- a **slice** (the default): the other dimensions are fixed (``at``; by default the middle of their
  range), and every pixel of the plane is an observation. Its greedy action is the agent's own
  ``predict``, and its cell the agent's own ``cells`` (the nearest codebook vector in the agent's
  metric, :meth:`avq.quantizer.Codebook.nearest_batch`), so the borders drawn are those of the Voronoi
  cells where they cut the plane. This works for every agent; agents without cells get no borders.
- a **projection** (``project=True``, agents with a codebook): the cell centres are projected onto
  the plane, each pixel belongs to the nearest projected centre in the agent's metric restricted to
  the two dimensions (the same quantizer, on the projected codebook), and is coloured by that cell's
  greedy action (``predict`` at its centre). A summary of all cells at once, not the policy at any one
  observation.

The range of each dimension is, first found: the one given (``bounds``), the agent's ``obs_bounds`` (the
range it was told), the observation space's finite bounds, the range of the cell centres (with a margin of
5% on each side).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces

from avq.agents.base import BaseAgent
from avq.quantizer import Codebook

__all__ = ["PolicyMap", "policy_map", "parse_dims", "parse_at", "parse_bounds", "dimension_names", "action_names"]

#: The names of the observation's dimensions and of the discrete actions of known tasks (by their id
#: without the version), for axis labels and legends.
_TASK_NAMES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "MountainCar": (("position", "velocity"), ("accelerate left", "don't accelerate", "accelerate right")),
    "CartPole": (
        ("cart position", "cart velocity", "pole angle", "pole angular velocity"),
        ("push left", "push right"),
    ),
    "Acrobot": (
        ("cos θ1", "sin θ1", "cos θ2", "sin θ2", "angular velocity θ1", "angular velocity θ2"),
        ("torque −1", "torque 0", "torque +1"),
    ),
    "Pendulum": (("x = cos θ", "y = sin θ", "angular velocity"), ()),
    "LunarLander": (
        ("x", "y", "x velocity", "y velocity", "angle", "angular velocity", "left leg contact", "right leg contact"),
        ("do nothing", "fire left engine", "fire main engine", "fire right engine"),
    ),
    "avq/GridMaze": (("x", "y"), ("north", "east", "south", "west")),
    "avq/RobotMaze": (("x", "y", *(f"sonar {k}" for k in range(1, 9))), ("north", "east", "south", "west")),
}


def _task_names(agent: BaseAgent) -> tuple[tuple[str, ...], tuple[str, ...]]:
    spec = getattr(agent.env, "spec", None)
    if spec is None:
        return (), ()
    key = f"{spec.namespace}/{spec.name}" if spec.namespace else spec.name
    return _TASK_NAMES.get(key, ((), ()))


def dimension_names(agent: BaseAgent) -> list[str]:
    """A name for each dimension of the agent's observations: the task's where known, else ``x0, x1, ...``."""
    known, _ = _task_names(agent)
    n = int(np.prod(agent.env.observation_space.shape or (0,)))
    return [known[d] if d < len(known) else f"x{d}" for d in range(n)]


def action_names(agent: BaseAgent) -> list[str]:
    """A name for each discrete action: the task's where known, else ``action 0, action 1, ...``."""
    _, known = _task_names(agent)
    n = int(getattr(agent.env.action_space, "n", 0))
    return [known[a] if a < len(known) and len(known) == n else f"action {a}" for a in range(n)]


@dataclass(frozen=True)
class PolicyMap:
    """An agent's greedy action (and cell) at each pixel of a plane through its observation space.

    Attributes:
        dims: The two dimensions ``(horizontal, vertical)``.
        names: The names of those two dimensions.
        xs: ``(nx,)`` the pixels' centres along ``dims[0]``; ``ys``: ``(ny,)`` along ``dims[1]``.
        actions: ``(ny, nx)`` the greedy action at each pixel: int for discrete actions, float (the first
            component) for continuous ones.
        cells: ``(ny, nx)`` the cell of each pixel, or None for an agent without cells.
        centres: ``(k, 2)`` the centres, in the plane, of the cells drawn (those present in a slice; all for a
            projection), or None.
        at: For a slice, the value of every other dimension (dimension -> value); empty for a projection.
        projected: Whether this is a projection (see :func:`policy_map`).
        action_names: The name of each discrete action (empty for continuous actions).
        action_label: What ``actions`` holds, for a legend or colour bar.
    """

    dims: tuple[int, int]
    names: tuple[str, str]
    xs: np.ndarray
    ys: np.ndarray
    actions: np.ndarray
    cells: np.ndarray | None
    centres: np.ndarray | None
    at: dict[int, float] = field(default_factory=dict)
    projected: bool = False
    action_names: tuple[str, ...] = ()
    action_label: str = "greedy action"


def _numbers(text: str, what: str, example: str) -> list[str]:
    parts = [p.strip() for p in str(text).split(",") if p.strip()]
    if not parts:
        raise ValueError(f"{what} is empty; give e.g. {example}")
    return parts


def parse_dims(text: str) -> tuple[int, int]:
    """``"0,1"`` -> ``(0, 1)`` (the range is checked against the agent by :func:`policy_map`)."""
    parts = _numbers(text, "dims", "0,1")
    try:
        dims = tuple(int(p) for p in parts)
    except ValueError:
        raise ValueError(f"dims {text!r}: give two dimension numbers separated by a comma, e.g. 0,1") from None
    if len(dims) != 2:
        raise ValueError(f"dims {text!r}: give exactly two dimension numbers separated by a comma, e.g. 0,1")
    return dims[0], dims[1]


def _dim_key(key: str, where: str, example: str) -> int:
    try:
        return int(key)
    except ValueError:
        raise ValueError(f"{where}: {key!r} is not a dimension number; give e.g. {example}") from None


def parse_at(text: str) -> dict[int, float]:
    """``"2=0.0,3=0.5"`` -> ``{2: 0.0, 3: 0.5}``: the value of each dimension held fixed in a slice."""
    out: dict[int, float] = {}
    for item in _numbers(text, "at", "2=0.0,3=0.0"):
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"at {item!r}: give DIM=VALUE, e.g. 2=0.0")
        dim = _dim_key(key, f"at {item!r}", "2=0.0")
        try:
            out[dim] = float(value)
        except ValueError:
            raise ValueError(f"at {item!r}: {value.strip()!r} is not a number; give e.g. {dim}=0.0") from None
    return out


def parse_bounds(text: str) -> dict[int, tuple[float, float]]:
    """``"1=-3:3"`` -> ``{1: (-3.0, 3.0)}``: the range drawn of a dimension."""
    out: dict[int, tuple[float, float]] = {}
    for item in _numbers(text, "bounds", "1=-3:3"):
        key, sep, value = item.partition("=")
        low, colon, high = value.partition(":")
        if not sep or not colon:
            raise ValueError(f"bounds {item!r}: give DIM=LOW:HIGH, e.g. 1=-3:3")
        dim = _dim_key(key, f"bounds {item!r}", "1=-3:3")
        try:
            out[dim] = (float(low), float(high))
        except ValueError:
            raise ValueError(f"bounds {item!r}: LOW and HIGH must be numbers, e.g. {dim}=-3:3") from None
    return out


def _box_size(agent: BaseAgent) -> int:
    space = agent.env.observation_space
    if not isinstance(space, spaces.Box) or len(space.shape) != 1:
        raise ValueError(
            f"a policy picture needs a flat Box observation space (a vector of numbers); this agent observes "
            f"{space}. Draw the partition of a maze with avq.plotting.plot_partition instead"
        )
    if space.shape[0] < 2:
        raise ValueError("a policy picture needs two dimensions to draw, and this observation space has one")
    return int(space.shape[0])


def _check_dim(d: Any, n: int, what: str, names: list[str]) -> int:
    if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or not 0 <= int(d) < n:
        dims = ", ".join(f"{k} ({name})" for k, name in enumerate(names))
        raise ValueError(f"{what}: this task has no dimension {d!r}; its dimensions are {dims}")
    return int(d)


def _ranges(
    agent: BaseAgent, n: int, bounds: Mapping[int, tuple[float, float]], centres: np.ndarray | None, names: list[str]
) -> np.ndarray:
    """``(n, 2)`` the range of each dimension (the module's docstring says which)."""
    space = agent.env.observation_space
    assert isinstance(space, spaces.Box)
    low, high = space.low.astype(float), space.high.astype(float)
    out = np.full((n, 2), np.nan)
    given = agent.get_params().get("obs_bounds") or [None] * n  # (the range the agent was told: grid, tiles)
    for d in range(n):
        if d in bounds:
            out[d] = bounds[d]
            if not np.all(np.isfinite(out[d])) or not out[d, 1] > out[d, 0]:
                lo, hi = sorted(out[d])
                fix = f"{lo:g}:{hi:g}" if np.isfinite([lo, hi]).all() and hi > lo else "-3:3"
                raise ValueError(
                    f"bounds of dimension {d} ({names[d]}): {out[d, 0]:g} to {out[d, 1]:g} is not a range to draw; "
                    f"give finite LOW below HIGH, e.g. bounds={{{d}: ({fix.replace(':', ', ')})}} "
                    f"(avq plot --bounds {d}={fix})"
                )
        elif given[d] is not None:
            out[d] = given[d]
        elif np.isfinite(low[d]) and np.isfinite(high[d]) and high[d] > low[d]:
            out[d] = (low[d], high[d])
        elif centres is not None and len(centres) and np.ptp(centres[:, d]) > 0:
            lo, hi = centres[:, d].min(), centres[:, d].max()
            out[d] = (lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo))
        if not np.all(np.isfinite(out[d])) or not out[d, 1] > out[d, 0]:
            raise ValueError(
                f"dimension {d} ({names[d]}) has no finite range to draw (the space's bounds are infinite and "
                f"the agent has no cell centres spread along it); give one, e.g. bounds={{{d}: (-3, 3)}} "
                f"(avq plot --bounds {d}=-3:3)"
            )
    return out


def _codebook(agent: BaseAgent) -> np.ndarray | None:
    vectors = getattr(agent, "codebook_", None)
    return None if vectors is None or agent.n_cells == 0 else np.asarray(vectors, dtype=np.float64)


def policy_map(
    agent: BaseAgent,
    dims: tuple[int, int] | str = (0, 1),
    at: Mapping[int, float] | str | None = None,
    project: bool = False,
    resolution: int = 400,
    bounds: Mapping[int, tuple[float, float]] | str | None = None,
) -> PolicyMap:
    """The agent's greedy action and cell at every pixel of the plane of ``dims``.

    A **slice** (the default) holds the other dimensions at ``at`` (the rest at the middle of their range):
    every pixel is an observation, its action the agent's ``predict`` and its cell the agent's ``cells`` (the
    nearest centre in the agent's own metric), so the borders are those of the Voronoi cells where they cut
    the plane; agents without cells get none. A **projection** (``project``, agents with a codebook)
    projects the cells' centres onto the plane: a pixel belongs to the nearest projected centre in the
    agent's metric restricted to the two dimensions, and takes that cell's greedy action (``predict`` at
    its centre). The range of each dimension is the first found of: ``bounds``, the agent's
    ``obs_bounds``, the space's finite bounds, the range of the cells' centres (and 5% on each side).

    Args:
        agent: A trained agent on a task with a flat ``Box`` observation space.
        dims: The dimensions across and up (or ``"0,1"``).
        at: For a slice, the value of some other dimensions (or ``"2=0.0,3=0.0"``); the rest are at the
            middle of their range. Not with ``project``.
        project: Project the cell centres instead of slicing (agents with a codebook).
        resolution: Pixels along each axis.
        bounds: The range of some dimensions (or ``"1=-3:3"``), where the defaults do not suit.

    Raises:
        ValueError: naming the value and what to give instead.
    """
    n = _box_size(agent)
    names = dimension_names(agent)
    dims = parse_dims(dims) if isinstance(dims, str) else dims
    at = parse_at(at) if isinstance(at, str) else dict(at or {})
    bounds = parse_bounds(bounds) if isinstance(bounds, str) else dict(bounds or {})
    if len(dims) != 2:
        raise ValueError(f"dims {dims!r}: give exactly two dimensions, e.g. (0, 1)")
    d0, d1 = (_check_dim(d, n, "dims", names) for d in dims)
    if d0 == d1:
        raise ValueError(f"dims are both {d0}; give two different dimensions, e.g. {d0},{(d0 + 1) % n}")
    for what, given in (("at", at), ("bounds", bounds)):
        for d in given:
            _check_dim(d, n, what, names)
    if project and at:
        raise ValueError("a projection fixes no dimension; give at (--at) for a slice or project (--project)")
    if set(at) & {d0, d1}:
        d = sorted(set(at) & {d0, d1})[0]
        raise ValueError(f"at fixes dimension {d}, which is drawn (dims {d0},{d1}); fix only the other dimensions")
    resolution = int(resolution)
    if resolution < 2:
        raise ValueError(f"resolution must be >= 2, not {resolution}")
    centres = _codebook(agent)
    if project and centres is None:
        raise ValueError(
            f"{type(agent).__name__} has no cell centres to project; draw a slice instead (no project / --project)"
        )
    ranges = _ranges(agent, n, bounds, centres, names)
    xs = _pixel_centres(ranges[d0], resolution)
    ys = _pixel_centres(ranges[d1], resolution)
    gx, gy = np.meshgrid(xs, ys)  # (ny, nx): row j is ys[j]
    plane = np.stack([gx.ravel(), gy.ravel()], axis=1)
    discrete = isinstance(agent.env.action_space, spaces.Discrete)
    cells: np.ndarray | None
    shown: np.ndarray | None
    if project:
        assert centres is not None
        scale = np.asarray(getattr(agent, "scale_", np.ones(n)), dtype=np.float64)
        cells = Codebook.from_vectors(centres[:, [d0, d1]], scale[[d0, d1]]).nearest_batch(plane)
        actions = _first_component(agent.predict(centres, deterministic=True)[0], len(centres))[cells]
        shown, fixed = centres[:, [d0, d1]], {}
    else:
        fixed = {d: float(at.get(d, ranges[d].mean())) for d in range(n) if d not in (d0, d1)}
        obs = np.empty((len(plane), n))
        for d, value in fixed.items():
            obs[:, d] = value
        obs[:, d0], obs[:, d1] = plane[:, 0], plane[:, 1]
        actions = _first_component(agent.predict(obs, deterministic=True)[0], len(obs))
        cells_of = getattr(agent, "cells", None)
        cells = np.asarray(cells_of(obs), dtype=np.int64) if callable(cells_of) and agent.n_cells > 0 else None
        shown = None
        if centres is not None and cells is not None:
            shown = centres[np.unique(cells)][:, [d0, d1]]
    return PolicyMap(
        dims=(d0, d1),
        names=(names[d0], names[d1]),
        xs=xs,
        ys=ys,
        actions=actions.reshape(len(ys), len(xs)),
        cells=None if cells is None else np.asarray(cells, dtype=np.int64).reshape(len(ys), len(xs)),
        centres=shown,
        at=fixed,
        projected=bool(project),
        action_names=tuple(action_names(agent)) if discrete else (),
        action_label="greedy action" if discrete else "greedy action (first component)",
    )


def _pixel_centres(limits: np.ndarray, resolution: int) -> np.ndarray:
    low, high = float(limits[0]), float(limits[1])
    step = (high - low) / resolution
    return low + step * (np.arange(resolution) + 0.5)


def _first_component(actions: Any, b: int) -> np.ndarray:
    """Discrete actions as ints; continuous ones by their first component."""
    a = np.asarray(actions)
    if np.issubdtype(a.dtype, np.integer):
        return a.reshape(b).astype(np.int64)
    return a.reshape(b, -1)[:, 0].astype(np.float64)
