"""Evaluating a learned policy on a maze: from every start, does the greedy policy reach the goal?"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from numba import njit

from avq._validate import check_int
from avq.agents.base import BaseAgent
from avq.agents.save_util import check_env_fits, env_signature
from avq.envs import as_env, same_env
from avq.envs.grid_maze import GridMaze, grid_move
from avq.envs.robot_geometry import RobotDynamics, robot_move, sonar_ranges
from avq.envs.robot_maze import RobotMaze

__all__ = ["evaluate_maze", "evaluate_policy", "success_rule", "SUCCESS_RULES"]


@njit(cache=True)
def _greedy_walks(walls, gx, gy, policy, starts, limit):
    """From each start, follow ``policy[y, x]`` until the goal or ``limit`` steps."""
    success = np.zeros(starts.shape[0], dtype=np.bool_)
    steps = np.zeros(starts.shape[0], dtype=np.int64)
    for k in range(starts.shape[0]):
        x, y = starts[k, 0], starts[k, 1]
        n = 0
        while n < limit:
            x, y, _, terminated, _ = grid_move(walls, x, y, policy[y, x], gx, gy)
            n += 1
            if terminated:
                success[k] = True
                break
        steps[k] = n
    return success, steps


@njit(cache=True)
def _robot_observations(grid, xs, ys, radius, dirs, sonar_range, observe_sonar, out):
    """RobotMaze's observation at each position (float32 values, as the environment gives them)."""
    sonar = np.empty(dirs.shape[0])
    for k in range(xs.shape[0]):
        out[k, 0] = np.float32(xs[k])
        out[k, 1] = np.float32(ys[k])
        if observe_sonar:
            sonar_ranges(grid, xs[k], ys[k], radius, dirs, sonar_range, sonar)
            for j in range(sonar.shape[0]):
                out[k, 2 + j] = np.float32(sonar[j])


@njit(cache=True)
def _robot_moves(grid, xs, ys, actions, move, radius, gx, gy, terminated):
    """One move of each robot, in place."""
    for k in range(xs.shape[0]):
        xs[k], ys[k], _, terminated[k], _ = robot_move(grid, xs[k], ys[k], actions[k], move, radius, gx, gy)


def _robot_walks(agent: BaseAgent, dyn: RobotDynamics, starts: Sequence[tuple[float, ...]], limit: int):
    """All greedy walks of a noise-free RobotMaze in lockstep: one batched ``predict`` per step."""
    xs = np.array([p[0] for p in starts], dtype=np.float64)
    ys = np.array([p[1] for p in starts], dtype=np.float64)
    k = len(starts)
    success = np.zeros(k, dtype=bool)
    steps = np.zeros(k, dtype=np.int64)
    alive = np.arange(k)
    dirs = dyn.sonar_directions
    n_obs = 2 + (dirs.shape[0] if dyn.observe_sonar else 0)
    gx, gy = dyn.goal
    for _ in range(limit):
        if len(alive) == 0:
            break
        obs = np.empty((len(alive), n_obs), dtype=np.float32)
        ax, ay = xs[alive], ys[alive]
        _robot_observations(dyn.grid, ax, ay, dyn.radius, dirs, dyn.sonar_range, dyn.observe_sonar, obs)
        actions, _ = agent.predict(obs.astype(np.float64), deterministic=True)
        terminated = np.zeros(len(alive), dtype=np.bool_)
        _robot_moves(dyn.grid, ax, ay, np.asarray(actions, dtype=np.int64), dyn.move, dyn.radius, gx, gy, terminated)
        xs[alive], ys[alive] = ax, ay
        steps[alive] += 1
        success[alive[terminated]] = True
        alive = alive[~terminated]
    return success, steps


def _step_limit(env: gym.Env, default: int = 100) -> int:
    spec = getattr(env, "spec", None)
    limit = getattr(spec, "max_episode_steps", None)
    return int(limit) if limit else default


def evaluate_maze(agent: BaseAgent, env: gym.Env | str, max_steps: int | None = None) -> dict[str, Any]:
    """Run the greedy policy from every free non-goal position of a maze.

    The greedy policy is the agent's own decision rule with exploration off: for
    AVQ agents the best action of the current cell, repeated while the cell stays
    the same (docs/explanation/paper.md#acting), which is the same as asking :meth:`avq.agents.BaseAgent.predict` with
    ``deterministic=True`` at every step because a frozen cell's best action does
    not change.

    Args:
        agent: A trained agent.
        env: A maze environment (``avq/GridMaze-v0`` or ``avq/RobotMaze-v0``, possibly
            wrapped). Use one that is not being trained on: it is reset for every start.
            On RobotMaze the starts are the centres of the free non-goal squares and the
            shortest path is the exact minimum number of moves. On a GridMaze with ``slip``,
            each walk slips as the env does (from its ``np_random``: seed it for repeatable figures).
        max_steps: Step limit of each run; default the env's step limit (100 on GridMaze).

    Returns:
        ``success_rate``: fraction of starts from which the goal is reached within the
        limit; ``path_ratio``: mean over successful starts of greedy steps divided by
        shortest-path steps (None when no start succeeds); ``outcomes``: one dict per
        start with ``start``, ``success``, ``steps`` and ``shortest``.

    Raises:
        ValueError: ``env`` is not a maze, or its spaces are not those the agent was trained on
            (a layout of another size, say): the rule of :func:`avq.load`, in
            :func:`avq.agents.save_util.check_env_fits`.
    """
    env = as_env(env)
    base: Any = env.unwrapped  # (a maze: duck-typed by its layout and, for a continuous one, start_positions)
    layout = getattr(base, "layout", None)
    if layout is None or not hasattr(layout, "distances"):
        raise ValueError(
            "evaluate_maze needs a maze environment (avq/GridMaze-v0 or avq/RobotMaze-v0); this one has no layout"
        )
    if isinstance(agent, BaseAgent):  # (any object with avq's predict() may be walked; only agents know their env)
        check_env_fits(env_signature(agent.env), env, "evaluate_maze")
    if hasattr(base, "start_positions"):  # continuous maze: square centres, exact lattice distances
        starts = [tuple(float(v) for v in p) for p in base.start_positions()]
        shortest = [int(base.shortest_steps(x, y)) for x, y in starts]
        default_limit = int(base.max_steps)
    else:
        starts = [(int(x), int(y)) for x, y in layout.free_positions(include_goal=False)]
        shortest = [int(layout.distances[y, x]) for x, y in starts]
        default_limit = _step_limit(env)
    limit = int(max_steps) if max_steps is not None else default_limit
    outcomes: list[dict[str, Any]] = []
    if isinstance(base, GridMaze) and base.dynamics.slip == 0.0:
        # The greedy policy is a function of the position: ask for every position at once and walk
        # the maze with its own compiled move (the same as stepping the environment).
        free = layout.free_positions(include_goal=True)
        actions, _ = agent.predict(free.astype(np.float64), deterministic=True)
        policy = np.zeros(layout.walls.shape, dtype=np.int64)
        policy[free[:, 1], free[:, 0]] = np.asarray(actions, dtype=np.int64)
        walks = np.array(starts, dtype=np.int64).reshape(-1, 2)
        dyn = base.dynamics
        success, steps = _greedy_walks(dyn.walls, dyn.goal[0], dyn.goal[1], policy, walks, limit)
        outcomes = [
            {"start": start, "success": bool(ok), "steps": int(n), "shortest": best}
            for start, ok, n, best in zip(starts, success, steps, shortest)
        ]
    elif type(base) is RobotMaze and base.dynamics.sonar_noise == 0.0:
        # The same walks as stepping the environment, all at once, with the maze's own compiled move.
        success, steps = _robot_walks(agent, base.dynamics, starts, limit)
        outcomes = [
            {"start": start, "success": bool(ok), "steps": int(n), "shortest": best}
            for start, ok, n, best in zip(starts, success, steps, shortest)
        ]
    for start, best in [] if outcomes else zip(starts, shortest):
        obs, _ = base.reset(options={"start": start})
        steps, success = 0, False
        while steps < limit:
            action, _ = agent.predict(obs, deterministic=True)
            obs, _, terminated, _, _ = base.step(action)
            steps += 1
            if terminated:
                success = True
                break
        outcomes.append({"start": start, "success": success, "steps": steps, "shortest": best})
    wins = [o for o in outcomes if o["success"]]
    ratio = float(np.mean([o["steps"] / o["shortest"] for o in wins])) if wins else None
    return {"success_rate": len(wins) / len(outcomes), "path_ratio": ratio, "outcomes": outcomes}


#: How success is read from an episode's end, for tasks that define it.
SUCCESS_RULES: dict[str, str] = {
    "avq/GridMaze-v0": "terminated",
    "avq/RobotMaze-v0": "terminated",
    "avq/SlabMaze-v0": "terminated",
    "MountainCar-v0": "terminated",
    "MountainCarContinuous-v0": "terminated",
    "Acrobot-v1": "terminated",
    "CartPole-v1": "truncated",
    "CartPole-v0": "truncated",
}


def success_rule(env: gym.Env) -> str | None:
    """``"terminated"``, ``"truncated"`` or None: what counts as success on this task."""
    spec = getattr(env, "spec", None)
    return SUCCESS_RULES.get(getattr(spec, "id", None) or "")


def _check_own_env(agent: BaseAgent, env: gym.Env) -> None:
    """``env`` must fit the agent (:func:`avq.agents.save_util.check_env_fits`); the agent's own environment is
    refused while an episode is under way and taken with a warning between episodes."""
    if same_env(env, agent.env):
        if agent.in_episode:
            raise ValueError(
                "evaluate_policy got the environment the agent is learning an episode on; give it one of its own "
                "(gymnasium.make with the same id): its resets would cut that episode"
            )
        warnings.warn(
            "evaluate_policy got the environment the agent learns on: its resets change the starts of the "
            "episodes the agent learns next (the same seed then gives another run); give it one of its own",
            stacklevel=3,
        )
    else:
        check_env_fits(env_signature(agent.env), env, "evaluate_policy")


def evaluate_policy(
    agent: BaseAgent,
    env: gym.Env | str,
    n_eval_episodes: int = 10,
    deterministic: bool = True,
    *,
    seed: int | None = 0,
    max_steps: int = 100_000,
    progress_bar: bool = False,
) -> dict[str, Any]:
    """Run ``n_eval_episodes`` with the agent's policy and summarize the returns.

    Called as Stable-Baselines3's ``evaluate_policy(model, env, n_eval_episodes, deterministic)``,
    but it returns a dict (``mean_return`` and ``std_return`` are SB3's pair, with more beside them).
    The environment is reset with ``seed`` once, so the same seed gives the same
    start states. ``success`` is reported where the task defines it (reaching the
    goal; for CartPole, lasting until the time limit; or ``info["is_success"]``).
    An episode that the environment has not ended after ``max_steps`` steps is cut
    there, counts as truncated, and is counted in ``capped``: its return is that of
    its first ``max_steps`` steps (a policy that loops forever on a task without a
    time limit, for instance).

    Args:
        agent: A trained agent (or anything with ``predict(obs, deterministic)``).
        env: An environment like the one it was trained on, or its id (``module:id`` too:
            :func:`avq.envs.as_env`). Not the one the agent learns on while an episode is under way (refused:
            the evaluation would cut it); between episodes it is taken with a warning, as its resets change the
            starts of the episodes the agent learns next.
        n_eval_episodes: Episodes to run.
        deterministic: The greedy policy (True) or the exploring one.
        seed: Seed of the first reset, an integer >= 0 (None: fresh entropy).
        max_steps: Steps after which an episode is cut.
        progress_bar: Show a tqdm progress bar of the episodes (drawn after a second;
            its count of steps moves within a long episode).

    Returns:
        ``episodes``, ``mean_return``, ``std_return``, ``mean_steps``, ``success_rate`` (or None),
        ``capped`` (the episodes cut at ``max_steps``), ``max_steps``, and the
        per-episode ``returns`` and ``steps``.
    """
    n_episodes = check_int("n_eval_episodes", n_eval_episodes, 1)
    check_int("max_steps", max_steps, 1)
    if seed is not None:
        seed = check_int("seed", seed, 0)
    env = as_env(env)
    if isinstance(agent, BaseAgent):  # (only agents know their env; any object with predict() may be evaluated)
        _check_own_env(agent, env)
    rule = success_rule(env)
    returns, lengths, successes = [], [], []
    capped = 0
    bar = None
    if progress_bar:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_episodes, unit="episode", desc="evaluate", delay=1.0, smoothing=0)
    obs, _ = env.reset(seed=seed)
    for ep in range(n_episodes):
        if ep:
            obs, _ = env.reset()
        total, steps, ok = 0.0, 0, None
        while True:
            action, _ = agent.predict(obs, deterministic=deterministic)
            obs, r, terminated, truncated, info = env.step(action)
            total += float(r)
            steps += 1
            if bar is not None and steps % 1000 == 0:
                bar.set_postfix_str(f"{steps} steps", refresh=False)
                bar.update(0)  # (redrawn at most every 0.1 s)
            if steps >= max_steps and not (terminated or truncated):
                truncated = True
                capped += 1
            if terminated or truncated:
                if "is_success" in info:
                    ok = bool(info["is_success"])
                elif rule == "terminated":
                    ok = bool(terminated)
                elif rule == "truncated":
                    ok = bool(truncated and not terminated)
                break
        returns.append(total)
        lengths.append(steps)
        successes.append(ok)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    rate = None if any(s is None for s in successes) else float(np.mean(cast(list[bool], successes)))
    return {
        "episodes": n_episodes,
        "mean_return": float(np.mean(returns)),
        "std_return": float(np.std(returns)),
        "mean_steps": float(np.mean(lengths)),
        "success_rate": rate,
        "capped": capped,
        "max_steps": int(max_steps),
        "returns": returns,
        "steps": lengths,
    }
