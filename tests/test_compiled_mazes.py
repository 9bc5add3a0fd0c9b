"""The contract between the mazes and the compiled loops (avq.envs.compiled): what a loop may read and write."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import RecordEpisodeStatistics, TimeLimit

import avq
from avq.agents import _maze_loop
from avq.envs import GridMaze, RobotMaze
from avq.envs.compiled import NO_LIMIT, compiled_maze


def test_grid_dynamics_are_frozen_read_only_and_match_the_layout():
    env = GridMaze(layout=["#S.", "..G"], start="fixed")
    d = env.dynamics
    assert d.walls.tolist() == [[True, False, False], [False, False, False]]
    assert d.goal == (2, 1) and d.fixed_start == (1, 0)
    assert d.starts.tolist() == [[1, 0], [2, 0], [0, 1], [1, 1]]  # free non-goal squares, row-major
    assert (d.goal_reward, d.move_reward, d.bump_reward) == (10.0, -1.0, -10.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.goal = (0, 0)
    with pytest.raises(ValueError):
        d.walls[0, 0] = False
    assert GridMaze(layout=["#S.", "..G"]).dynamics.fixed_start is None


def test_robot_dynamics_describe_the_robot_and_its_sonar():
    env = RobotMaze(layout=["S.", ".G"], start="fixed", move=0.5, radius=0.25, observe_sonar=True, max_steps=30)
    d = env.dynamics
    assert d.grid.shape == (4, 4) and d.grid[0].all() and not d.grid[1:3, 1:3].any()  # padded by a ring of walls
    assert d.goal == (1.0, 1.0) and d.fixed_start == (0.0, 0.0)
    assert (d.move, d.radius, d.max_steps, d.observe_sonar, d.sonar_noise) == (0.5, 0.25, 30, True, 0.0)
    assert d.sonar_directions.shape == (16, 2) and not d.sonar_directions.flags.writeable


def test_the_step_limit_in_force_comes_from_gymnasiums_time_limit_and_the_robots_own():
    assert compiled_maze(gym.make("avq/GridMaze-v0")).max_episode_steps == 100
    assert compiled_maze(gym.make("avq/GridMaze-v0", max_episode_steps=40)).max_episode_steps == 40
    assert compiled_maze(TimeLimit(GridMaze(), 37)).max_episode_steps == 37
    assert compiled_maze(GridMaze()).max_episode_steps == NO_LIMIT
    assert compiled_maze(gym.make("avq/RobotMaze-v0", max_steps=50)).max_episode_steps == 50
    assert compiled_maze(TimeLimit(RobotMaze(max_steps=50), 20)).max_episode_steps == 20
    # A TimeLimit of one's own around gymnasium.make's: the smaller limit applies.
    assert compiled_maze(TimeLimit(gym.make("avq/GridMaze-v0"), 60)).max_episode_steps == 60
    assert compiled_maze(TimeLimit(TimeLimit(GridMaze(), 50), 60)).max_episode_steps == 50


def test_only_gymnasiums_standard_wrappers_and_the_mazes_themselves_are_compiled():
    class MyMaze(GridMaze):
        pass

    assert compiled_maze(RecordEpisodeStatistics(gym.make("avq/GridMaze-v0"))) is None
    assert compiled_maze(MyMaze()) is None  # a subclass may step differently
    assert _maze_loop.plan(gym.make("avq/RobotMaze-v0", sonar_noise=0.1)) is None
    assert _maze_loop.plan(gym.make("avq/RobotMaze-v0"), grid_only=True) is None
    assert _maze_loop.plan(gym.make("avq/RobotMaze-v0")) is not None


def test_episode_state_is_read_and_written_so_that_step_goes_on_from_there():
    env = gym.make("avq/GridMaze-v0")
    env.reset(seed=0, options={"start": (1, 1)})
    maze = compiled_maze(env)
    env.step(2)  # South: (1, 2) is free in lau2002
    assert maze.episode_state() == (1, 2, 1)
    maze.set_episode_state(3, 1, 98)
    obs, _, _, truncated, _ = env.step(1)
    assert obs.tolist() == [4.0, 1.0] and not truncated
    _, _, _, truncated, _ = env.step(3)
    assert truncated  # the TimeLimit counted on from 98
    robot = gym.make("avq/RobotMaze-v0", max_steps=10)
    robot.reset(seed=0)
    compiled_maze(robot).set_episode_state(1.0, 1.0, 9)
    assert robot.unwrapped.position == (1.0, 1.0)
    assert robot.step(0)[3]  # truncated at its own limit


@pytest.mark.parametrize(
    "make",
    [lambda k: TimeLimit(GridMaze(), k), lambda k: TimeLimit(gym.make("avq/GridMaze-v0"), k)],
    ids=["bare", "around-gym-make"],
)
@pytest.mark.parametrize("limit", [7, 23])
def test_a_time_limit_the_user_set_applies_to_fused_training(limit, make):
    runs = []
    for fused in (True, False):
        agent = avq.make_agent("avq-paper", make(limit), seed=1, fused=fused)
        assert (agent._fused_runner() is not None) == fused
        runs.append(agent.learn(total_episodes=40).learn(total_timesteps=55))
    a, b = runs
    steps = a.episode_history()["steps"]
    assert steps.max() == limit and np.array_equal(steps, b.episode_history()["steps"])
    assert np.array_equal(a.q_, b.q_) and np.array_equal(a.codebook_, b.codebook_)


def test_the_mazes_arguments_are_read_only_so_the_dynamics_cannot_go_stale():
    env = RobotMaze(max_steps=30)
    for name in ("max_steps", "move", "radius", "sonar_noise", "sonar_range", "observe_sonar", "start"):
        with pytest.raises(AttributeError):
            setattr(env, name, getattr(env, name))
    with pytest.raises(AttributeError):
        GridMaze().start = "fixed"
    assert env.max_steps == env.dynamics.max_steps == 30


def test_tabular_is_not_fused_on_a_maze_larger_than_max_states():
    agent = avq.make_agent("tabular", gym.make("avq/GridMaze-v0"), seed=0, max_states=24)
    assert agent._fused_runner() is None
    with pytest.raises(ValueError, match="max_states"):
        agent.learn(total_episodes=200)
    assert avq.make_agent("tabular", gym.make("avq/GridMaze-v0"), seed=0)._fused_runner() is not None
