"""Tests for IrrelevantDims: k dimensions of noise or of a slow walk appended to a task's observations."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding
from gymnasium.utils.env_checker import check_env

import avq
from avq.envs import IrrelevantDims, SlabMaze


def wrapped_check(env: gym.Env, skip_render_check: bool) -> None:
    """``check_env`` on a wrapper, every warning an error but the one that says it is a wrapper."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=".*is different from the unwrapped version")
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")  # CartPole
        check_env(env, skip_render_check=skip_render_check)


@pytest.mark.parametrize("kind", ["noise", "walk"])
@pytest.mark.parametrize("task", ["MountainCar-v0", "CartPole-v1", "avq/SlabMaze-v0"])
def test_check_env_passes(task, kind):
    maze = task.startswith("avq/")
    env = gym.make(task, render_mode="ansi") if maze else gym.make(task)
    wrapped_check(IrrelevantDims(env, 3, kind), skip_render_check=not maze)  # (classic control draws with pygame)


def test_spaces_are_the_tasks_then_the_unit_interval():
    env = IrrelevantDims(gym.make("MountainCar-v0"), 2)
    space = env.observation_space
    assert space.shape == (4,) and space.dtype == np.float32
    np.testing.assert_array_equal(space.low, np.array([-1.2, -0.07, 0, 0], dtype=np.float32))
    np.testing.assert_array_equal(space.high, np.array([0.6, 0.07, 1, 1], dtype=np.float32))
    assert env.action_space == gym.spaces.Discrete(3)


def test_an_integer_box_becomes_float64():
    class Counts(gym.Env):
        observation_space = gym.spaces.Box(0, 5, shape=(2,), dtype=np.int64)
        action_space = gym.spaces.Discrete(2)

    assert IrrelevantDims(Counts(), 1).observation_space.dtype == np.float64


@pytest.mark.parametrize("kind", ["noise", "walk"])
def test_the_tasks_observation_is_unchanged_and_the_new_dimensions_stay_in_the_unit_interval(kind):
    env, twin = IrrelevantDims(gym.make("CartPole-v1"), 3, kind, walk_step=0.3), gym.make("CartPole-v1")
    obs, _ = env.reset(seed=5)
    inner, _ = twin.reset(seed=5)
    rows = [obs]
    np.testing.assert_array_equal(obs[:4], inner)
    actions = np.random.default_rng(0).integers(2, size=500)
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        inner, reward_t, terminated_t, truncated_t, _ = twin.step(a)
        np.testing.assert_array_equal(obs[:4], inner)
        assert (reward, terminated, truncated) == (reward_t, terminated_t, truncated_t)
        rows.append(obs)
        if terminated or truncated:
            (obs, _), (inner, _) = env.reset(seed=len(rows)), twin.reset(seed=len(rows))
            np.testing.assert_array_equal(obs[:4], inner)
    extra = np.array(rows)[:, 4:]
    assert extra.min() >= 0.0 and extra.max() <= 1.0
    assert extra.min() < 0.1 and extra.max() > 0.9  # (both kinds visit the whole interval)


def test_walk_moves_by_at_most_its_step_and_is_reflected_at_the_bounds():
    env = IrrelevantDims(SlabMaze(dims=2, walls=[]), 4, "walk", walk_step=0.05)
    obs, _ = env.reset(seed=0)
    walk = [obs[2:]]
    for _ in range(3000):
        obs, _, terminated, truncated, _ = env.step(0 if len(walk) % 2 else 1)  # (back and forth: no goal)
        walk.append(obs[2:])
    steps = np.abs(np.diff(np.array(walk, dtype=np.float64), axis=0))
    assert steps.max() <= 0.05 + 1e-6 and steps.mean() > 0.01
    assert min(np.min(walk), 1 - np.max(walk)) < 0.01  # it reached a bound and came back


def test_noise_is_drawn_again_every_step():
    env = IrrelevantDims(gym.make("MountainCar-v0"), 2)
    env.reset(seed=0)
    draws = np.array([env.step(1)[0][2:] for _ in range(2000)])
    assert len(np.unique(draws[:, 0])) == 2000
    assert draws.mean() == pytest.approx(0.5, abs=0.02)


@pytest.mark.parametrize("kind", ["noise", "walk"])
def test_the_same_seed_gives_the_same_observations_and_a_stream_apart_from_the_tasks(kind):
    def run(seed):
        env = IrrelevantDims(gym.make("MountainCar-v0"), 3, kind)
        return np.array([env.reset(seed=seed)[0]] + [env.step(2)[0] for _ in range(50)])

    np.testing.assert_array_equal(run(1), run(1))
    assert not np.array_equal(run(1)[:, 2:], run(2)[:, 2:])
    task_stream = seeding.np_random(1)[0].random(3)  # (what the task's own generator draws first)
    assert not np.allclose(run(1)[0, 2:], task_stream.astype(np.float32))


def test_k_zero_is_the_task_itself():
    env, twin = IrrelevantDims(gym.make("MountainCar-v0"), 0), gym.make("MountainCar-v0")
    assert env.observation_space == twin.observation_space
    np.testing.assert_array_equal(env.reset(seed=3)[0], twin.reset(seed=3)[0])
    np.testing.assert_array_equal(env.step(0)[0], twin.step(0)[0])


class Grid(gym.Env):
    """A task whose observations are a Box of shape (2, 2)."""

    observation_space = gym.spaces.Box(0, 1, shape=(2, 2))
    action_space = gym.spaces.Discrete(2)


@pytest.mark.parametrize(
    ("make", "args", "match"),
    [
        (lambda: gym.make("MountainCar-v0"), (-1,), "k must be an integer >= 0, not -1"),
        (lambda: gym.make("MountainCar-v0"), (1.5,), "k must be an integer >= 0, not 1.5"),
        (lambda: gym.make("MountainCar-v0"), (True,), "k must be an integer >= 0, not True"),
        (lambda: gym.make("MountainCar-v0"), (2, "gauss"), "kind must be 'noise' or 'walk', not 'gauss'"),
        (lambda: gym.make("MountainCar-v0"), (2, "walk", 0.0), r"walk_step must be in \(0.0, 1.0\], not 0.0"),
        (lambda: gym.make("MountainCar-v0"), (2, "walk", 1.5), r"walk_step must be in \(0.0, 1.0\], not 1.5"),
        (
            lambda: gym.make("FrozenLake-v1"),
            (2,),
            r"needs a task whose observation space is a Box of shape \(n,\), not Discrete\(16\); flatten it first",
        ),
        (Grid, (2,), r"a Box of shape \(n,\), not Box\(0.0, 1.0, \(2, 2\), float32\)"),
    ],
)
def test_bad_input_raises_naming_the_value_and_the_fix(make, args, match):
    with pytest.raises(ValueError, match=match):
        IrrelevantDims(make(), *args)


def test_an_avq_agent_learns_on_a_wrapped_task_without_error():
    agent = avq.make_agent("avq", IrrelevantDims(gym.make("MountainCar-v0"), 2), seed=0)
    agent.learn(total_episodes=2)
    assert agent.codebook_.shape[1] == 4


def test_the_example_of_the_environments_page_runs():
    page = Path(__file__).resolve().parents[1] / "docs" / "reference" / "environments.md"
    blocks = re.findall(r"^```python\n(.*?)^```", page.read_text(encoding="utf-8"), re.M | re.S)
    assert blocks
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, str(page), "exec"), namespace)


def test_a_wrapped_task_gets_the_general_defaults_not_those_chosen_for_its_own_observations():
    # CartPole-v1's entry weights its 4 dimensions one by one (scale_factor): not 6 dimensions
    agent = avq.make_agent("avq", IrrelevantDims(gym.make("CartPole-v1"), 2), seed=0)
    assert agent.defaults_used.env_id is None and agent.defaults_used.key == "*"
    agent.learn(total_episodes=2)
    assert avq.make_agent("avq", IrrelevantDims(gym.make("CartPole-v1"), 0)).defaults_used.key == "CartPole-v1"
