"""Evaluating a learned policy on a maze: from every start, does the greedy policy reach the goal?"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from avq.agents.base import BaseAgent

__all__ = ["evaluate_maze"]


def _step_limit(env: gym.Env, default: int = 100) -> int:
    spec = getattr(env, "spec", None)
    limit = getattr(spec, "max_episode_steps", None)
    return int(limit) if limit else default


def evaluate_maze(agent: BaseAgent, env: gym.Env, max_steps: int | None = None) -> dict[str, Any]:
    """Run the greedy policy from every free non-goal position of a maze.

    The greedy policy is the agent's own decision rule with exploration off: for
    AVQ agents the best action of the current cell, repeated while the cell stays
    the same (SPEC §2), which is the same as asking :meth:`predict` with
    ``deterministic=True`` at every step because a frozen cell's best action does
    not change.

    Args:
        agent: A trained agent.
        env: A maze environment (``avq/GridMaze-v0``, possibly wrapped). Use one that
            is not being trained on: it is reset for every start.
        max_steps: Step limit of each run; default the env's ``max_episode_steps`` or 100.

    Returns:
        ``success_rate``: fraction of starts from which the goal is reached within the
        limit; ``path_ratio``: mean over successful starts of greedy steps divided by
        shortest-path steps (None when no start succeeds); ``outcomes``: one dict per
        start with ``start``, ``success``, ``steps`` and ``shortest``.
    """
    base = env.unwrapped
    layout = getattr(base, "layout", None)
    if layout is None or not hasattr(layout, "distances"):
        raise ValueError("evaluate_maze needs a maze environment (avq/GridMaze-v0); this one has no layout")
    limit = int(max_steps) if max_steps is not None else _step_limit(env)
    outcomes = []
    for x, y in layout.free_positions(include_goal=False):
        obs, _ = base.reset(options={"start": (int(x), int(y))})
        steps, success = 0, False
        while steps < limit:
            action, _ = agent.predict(obs, deterministic=True)
            obs, _, terminated, _, _ = base.step(action)
            steps += 1
            if terminated:
                success = True
                break
        outcomes.append(
            {"start": (int(x), int(y)), "success": success, "steps": steps,
             "shortest": int(layout.distances[y, x])}
        )
    wins = [o for o in outcomes if o["success"]]
    ratio = float(np.mean([o["steps"] / o["shortest"] for o in wins])) if wins else None
    return {"success_rate": len(wins) / len(outcomes), "path_ratio": ratio, "outcomes": outcomes}
