"""Tests for PotentialShaping (rewards plus the change of a potential) and SlabMaze.goal_distance, its potential
for the slab maze."""

from __future__ import annotations

import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from avq.envs import PotentialShaping, SlabMaze

#: One slab across axis 0 at 0.5, open where 0.2 <= x[1] <= 0.4.
WALL = [(0, 0.5, (0.0, 0.2), (1.0, 0.4))]


def test_check_env_passes():
    maze = gym.make("avq/SlabMaze-v0", dims=3, render_mode="ansi")
    env = PotentialShaping(maze, lambda obs: -maze.unwrapped.goal_distance(obs))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=".*is different from the unwrapped version")
        check_env(env)


def test_goal_distance_counts_the_moves_below_the_goals_face():
    maze = SlabMaze(3, move=0.1, goal_size=0.2)  # (the goal: every coordinate >= 0.8)
    assert maze.goal_distance([0.5, 0.8, 0.9]) == pytest.approx(3.0, abs=1e-5)  # (0.3 below on axis 0 only)
    assert maze.goal_distance([0.0, 0.0, 0.0]) == pytest.approx(24.0, abs=1e-5)
    assert maze.goal_distance([0.85, 0.9, 1.0]) == 0.0
    rows = maze.goal_distance(np.array([[0.75, 0.8, 0.8], [0.6, 0.7, 0.05]]))
    np.testing.assert_allclose(rows, [0.5, 2.0 + 1.0 + 7.5])


def test_goal_distance_rounds_away_float32_noise_on_a_walk_from_the_fixed_start():
    maze = SlabMaze(6, walls=[], start="fixed")
    obs, _ = maze.reset(seed=0)
    assert obs.dtype == np.float32 and maze.goal_distance(obs) == 51.0  # (8.5 moves below 0.9 on each axis)
    for a in (0, 2, 4, 0, 10, 6):
        after, *_ = maze.step(a)
        assert maze.goal_distance(obs) - maze.goal_distance(after) == 1.0
        obs = after


@pytest.mark.parametrize("dims", [4, 6, 8])
def test_goal_distance_changes_by_whole_or_half_moves_exactly_on_random_walks_from_the_fixed_start(dims):
    # A long random walk through the lattice from the fixed start (no slabs), in the float32 observations: each axis
    # is rounded, so no move changes the distance by a whole move and a millionth (rounding the sum did, from d = 4).
    maze = SlabMaze(dims, walls=[], start="fixed", max_steps=100_000)
    obs, _ = maze.reset(seed=0)
    changes = set()
    for a in np.random.default_rng(dims).integers(0, 2 * dims, size=3_000):
        after, _, terminated, *_ = maze.step(int(a))
        changes.add(float(maze.goal_distance(obs) - maze.goal_distance(after)))
        obs = after
        if terminated:
            obs, _ = maze.reset()
    assert changes <= {-1.0, -0.5, 0.0, 0.5, 1.0} and {-1.0, 1.0} <= changes


def test_goal_distance_is_no_more_than_a_walks_moves():
    maze = SlabMaze(2, walls=WALL, move=0.1, goal_size=0.1, start="fixed")
    start = np.array([0.05, 0.05])
    assert maze.goal_distance(start) == pytest.approx(17.0, abs=1e-5)
    assert maze.shortest_steps(start) == 18  # (9 moves along each axis: 0.05 + 9 * 0.1 is the first point past 0.9)


@pytest.mark.parametrize("bad", [[0.1, 0.2, 0.3], [[0.1], [0.2]], "near", np.zeros((2, 2, 2))])
def test_goal_distance_refuses_points_of_the_wrong_shape(bad):
    with pytest.raises(ValueError, match=r"points must be 2 numbers or an \(n, 2\) array"):
        SlabMaze(2).goal_distance(bad)


def test_each_reward_is_the_tasks_plus_the_change_of_the_potential():
    maze = SlabMaze(2, walls=WALL, move=0.1, goal_size=0.1, start="fixed")
    env = PotentialShaping(maze, lambda obs: -maze.goal_distance(obs))
    env.reset(seed=0)  # at (0.05, 0.05): phi -17
    _, r, *_, info = env.step(0)  # +0.1 along axis 0: -1, and one move nearer the goal
    assert info["unshaped_reward"] == -1.0 and r == pytest.approx(0.0, abs=1e-5)
    _, r, *_, info = env.step(1)  # back: -1, and one move further
    assert info["unshaped_reward"] == -1.0 and r == pytest.approx(-2.0, abs=1e-5)
    _, r, *_, info = env.step(3)  # -0.1 along axis 1 leaves the cube: a collision, where it was
    assert info["collision"] and info["unshaped_reward"] == -10.0 and r == pytest.approx(-10.0, abs=1e-5)


def test_a_discount_weighs_the_new_potential():
    maze = SlabMaze(2, move=0.1, goal_size=0.1, start="fixed")
    env = PotentialShaping(maze, lambda obs: -maze.goal_distance(obs), gamma=0.5)
    env.reset(seed=0)  # phi -17
    _, r, *_ = env.step(0)  # phi -16: -1 + 0.5 * -16 + 17
    assert r == pytest.approx(8.0, abs=1e-5)


def test_a_terminated_episode_ends_at_potential_zero_and_the_return_changes_by_the_first_potential():
    maze = SlabMaze(2, walls=[], move=0.1, goal_size=0.1, start="fixed")
    env = PotentialShaping(maze, lambda obs: 100.0 - maze.goal_distance(obs))  # (not 0 in the goal: 100 there)
    env.reset(seed=0)
    shaped = unshaped = 0.0
    terminated = False
    for a in [0, 2] * 9:
        _, r, terminated, truncated, info = env.step(a)
        shaped, unshaped = shaped + r, unshaped + info["unshaped_reward"]
        if terminated:
            break
    assert terminated
    assert unshaped == pytest.approx(-17.0 + 10.0, abs=1e-5)
    # (the last step adds -phi(s), not 100 - phi(s): the return changes by the first potential only)
    assert shaped == pytest.approx(unshaped - (100.0 - 17.0), abs=1e-5)


def test_a_truncated_episode_keeps_the_last_potential():
    maze = SlabMaze(2, walls=[], move=0.1, goal_size=0.1, start="fixed", max_steps=3)
    env = PotentialShaping(maze, lambda obs: -maze.goal_distance(obs))
    env.reset(seed=0)
    shaped = 0.0
    for _ in range(3):
        _, r, terminated, truncated, _ = env.step(0)
        shaped += r
    assert truncated and not terminated
    assert shaped == pytest.approx(-3.0 + (-14.0) - (-17.0), abs=1e-5)


def test_a_reset_starts_from_the_new_observations_potential():
    maze = SlabMaze(2, walls=[], move=0.1, goal_size=0.1)
    env = PotentialShaping(maze, lambda obs: -maze.goal_distance(obs))
    env.reset(seed=3, options={"start": [0.05, 0.05]})
    env.step(0)
    env.reset(options={"start": [0.45, 0.25]})  # (phi -11, not the -16 the last episode ended at)
    _, r, *_ = env.step(0)
    assert r == pytest.approx(0.0, abs=1e-5)


def test_bad_potentials_and_discounts_are_refused_by_name():
    maze = SlabMaze(2)
    with pytest.raises(TypeError, match="potential must be a function of one observation.*not 3"):
        PotentialShaping(maze, 3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="gamma"):
        PotentialShaping(maze, lambda obs: 0.0, gamma=0.0)
    for value in (float("nan"), float("inf"), "far", "3", None, True, np.bool_(False), np.array([2.0]), 1j):
        env = PotentialShaping(maze, lambda obs, v=value: v)
        with pytest.raises(ValueError, match=rf"potential\(\[.*\]\) returned {re.escape(repr(value))}, not a finite"):
            env.reset(seed=0)


def test_a_potential_that_fails_at_a_step_names_the_observation():
    maze = SlabMaze(2, walls=[], move=0.1, goal_size=0.1, start="fixed")
    env = PotentialShaping(maze, lambda obs: -maze.goal_distance(obs) if obs[0] < 0.1 else float("nan"))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"potential\(\[0\.15"):
        env.step(0)


def test_stacked_shapings_keep_the_tasks_own_reward_and_add_both_changes():
    maze = SlabMaze(2, walls=[], move=0.1, goal_size=0.1, start="fixed")
    env = PotentialShaping(PotentialShaping(maze, lambda obs: -maze.goal_distance(obs)), lambda obs: 5.0 * obs[0])
    env.reset(seed=0)
    _, r, *_, info = env.step(0)  # -1, +1 from the first potential, +0.5 from the second
    assert info["unshaped_reward"] == -1.0 and r == pytest.approx(0.5, abs=1e-5)
