"""The fused GridMaze loop and the generic path give identical results (issue: same algorithm on both paths)."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import RecordEpisodeStatistics

import avq

#: The general Sarsa(λ) defaults (``avq-sarsa``: the value-change trigger, the maze options at the class's
#: defaults), with the budget of before.
GENERAL = ("avq-sarsa", {"max_cells": 10_000})
#: The Sarsa(λ) maze rules with the cycle split and a decaying epsilon (``avq`` on the grid maze before the planner).
MAZE = ("avq-maze", {"cycle_split": True, "epsilon": 0.2, "epsilon_decay": 0.995, "epsilon_min": 0.01})
#: Every rule of the kernels: the paper's, the maze rules (with the splits), the general defaults; and ``avq`` on
#: the maze, the planner with merging.
VARIANTS = [("avq-paper", {}), MAZE, GENERAL, ("avq", {})]


def run(name, fused, seed, overrides=None, **learn):
    env = gym.make("avq/GridMaze-v0")
    agent = avq.make_agent(name, env, seed=seed, fused=fused, **(overrides or {}))
    agent.learn(**learn)
    return agent


def same(a, b):
    assert np.array_equal(a.codebook_, b.codebook_)
    assert np.array_equal(a.q_, b.q_)
    ha, hb = a.episode_history(), b.episode_history()
    for key in ("steps", "return", "n_cells", "appends", "merges", "refused", "decisions"):
        assert np.array_equal(ha[key], hb[key]), key
    assert a.num_timesteps == b.num_timesteps and a.num_episodes == b.num_episodes


@pytest.mark.parametrize(
    "name, overrides",
    VARIANTS + [("avq-maze", {**MAZE[1], "explore_bonus": 2.0, "prune_after": 20, "make_room": True})],
    ids=["avq-paper", "avq-maze", "avq-general", "avq", "avq-bonus-prune"],
)
@pytest.mark.parametrize("seed", [0, 1])
def test_fused_and_generic_paths_are_identical(name, overrides, seed):
    same(run(name, True, seed, overrides, total_episodes=300), run(name, False, seed, overrides, total_episodes=300))


def test_paths_can_alternate_mid_episode():
    # 1234 steps fused, 1000 generic, then fused again: the same as one generic run.
    env = gym.make("avq/GridMaze-v0")
    mixed = avq.make_agent("avq-paper", env, seed=4)
    mixed.learn(total_timesteps=1234)
    mixed.fused = False
    mixed.learn(total_timesteps=1000)
    mixed.fused = True
    mixed.learn(total_timesteps=777)
    same(mixed, run("avq-paper", False, 4, total_timesteps=3011))


def test_fused_path_respects_callbacks_and_fixed_starts():
    calls = []

    def stop_at_7(agent, record):
        calls.append(record["episode"])
        return record["episode"] < 7

    for fused in (True, False):
        env = gym.make("avq/GridMaze-v0", start="fixed")
        agent = avq.make_agent("avq-paper", env, seed=2, fused=fused)
        agent.learn(total_episodes=50, callback=stop_at_7)
        assert agent.num_episodes == 7
    assert calls == list(range(1, 8)) * 2


def test_other_wrappers_fall_back_to_the_generic_path():
    env = RecordEpisodeStatistics(gym.make("avq/GridMaze-v0"))
    agent = avq.make_agent("avq-paper", env, seed=0)
    assert agent._fused_runner() is None
    agent.learn(total_episodes=3)
    assert len(env.return_queue) == 3  # the wrapper saw every episode
    assert avq.make_agent("avq-paper", gym.make("avq/GridMaze-v0"), seed=0)._fused_runner() is not None


@pytest.mark.parametrize("kwargs", [{}, {"observe_sonar": True}, {"start": "fixed", "move": 0.5}])
@pytest.mark.parametrize(
    "name, overrides",
    VARIANTS + [("avq-maze", {"cycle_split": True, "explore_bonus": 2.0, "max_cells": 10_000})],
    ids=["avq-paper", "avq-maze", "avq-general", "avq", "avq-maze-cycle-split-bonus"],
)
def test_fused_robot_maze_is_identical_to_the_generic_path(name, overrides, kwargs):
    runs = []
    for fused in (True, False):
        agent = avq.make_agent(name, gym.make("avq/RobotMaze-v0", **kwargs), seed=3, fused=fused, **overrides)
        runs.append(agent.learn(total_episodes=25))
    same(*runs)


def test_noisy_sonar_uses_the_generic_path():
    for name in ("avq", "avq-maze"):  # (the planner and AVQ Sarsa)
        agent = avq.make_agent(name, gym.make("avq/RobotMaze-v0", sonar_noise=0.1), seed=0).learn(total_episodes=1)
        assert agent._fused_runner() is None
        agent = avq.make_agent(name, gym.make("avq/RobotMaze-v0"), seed=0).learn(total_episodes=1)
        assert agent._fused_runner() is not None


@pytest.mark.parametrize("start", ["random", "fixed"])
def test_fused_tabular_grid_maze_is_identical_to_the_generic_path(start):
    runs = []
    for fused in (True, False):
        agent = avq.make_agent("tabular", gym.make("avq/GridMaze-v0", start=start), seed=8, fused=fused)
        agent.learn(total_episodes=150).learn(total_timesteps=321).learn(total_episodes=50)
        runs.append(agent)
    a, b = runs
    assert np.array_equal(a.states_, b.states_) and np.array_equal(a.q_, b.q_)
    for key in ("steps", "return", "n_cells", "appends"):
        assert np.array_equal(a.episode_history()[key], b.episode_history()[key])
