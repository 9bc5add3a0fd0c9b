"""Mistakes in the observation bounds or the cell budget, and observations that are not finite during
`avq train`: one line naming the value and the fix, exit code 2, and nothing written before lost."""

import csv

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.envs.classic_control import CartPoleEnv

import avq
from avq.cli import main

NAN_ENV = "avqtest/CartPoleNaN-v0"


class NaNAt(gym.Wrapper):
    """CartPole whose observation at step ``step`` of episode ``episode`` (both 1-based) has a NaN velocity."""

    def __init__(self, env, episode, step):
        super().__init__(env)
        self.bad = (episode, step)
        self.episode = self.t = 0

    def reset(self, *, seed=None, options=None):
        self.episode += 1
        self.t = 0
        return self.env.reset(seed=seed, options=options)

    def step(self, action):
        obs, r, terminated, truncated, info = self.env.step(action)
        self.t += 1
        if (self.episode, self.t) == self.bad:
            obs = obs.copy()
            obs[1] = np.nan
        return obs, r, terminated, truncated, info


def train(tmp_path, capsys, *args):
    code = main(
        ["train", "--env", "CartPole-v1", "--episodes", "2", "--no-progress", "--out", str(tmp_path / "run"), *args]
    )
    lines = capsys.readouterr().err.strip().splitlines()
    return code, lines


@pytest.mark.parametrize("agent", ["avq", "tiles"])
@pytest.mark.parametrize(
    ("value", "told"),
    [
        (
            "obs_bounds=[[-2.4,2.4],[-3,3],[-0.21,0.21]]",
            "obs_bounds must have 4 entries (one per observation dimension), not 3: [[-2.4, 2.4], [-3.0, 3.0], [-0.21, 0.21]]; "
            "give a (low, high) per dimension, None for those whose own bounds are fine",
        ),
        (
            "obs_bounds=[[-2.4,2.4],[3,-3],null,null]",
            "obs_bounds[1] is [3, -3], whose low is not below its high; give (low, high) with low < high",
        ),
        (
            "obs_bounds=[[-2.4,2.4],[0.5,0.5],null,null]",
            "obs_bounds[1] is [0.5, 0.5], whose low is not below its high; give (low, high) with low < high",
        ),
        (
            "obs_bounds=[[-2.4,2.4],[-.inf,3],null,null]",
            "obs_bounds[1] is [-inf, 3], which is not finite; give finite numbers (low, high), or None to keep the "
            "space's bounds for that dimension",
        ),
        (
            "obs_bounds=[[-2.4,2.4],[-3,.nan],null,null]",
            "obs_bounds[1] is [-3, nan], which is not finite; give finite numbers (low, high), or None to keep the "
            "space's bounds for that dimension",
        ),
    ],
)
def test_bad_obs_bounds_name_the_entry_the_problem_and_the_fix(tmp_path, capsys, agent, value, told):
    code, lines = train(tmp_path, capsys, "--agent", agent, "--set", value)
    assert code == 2 and lines == [f"avq: error: {told}"]
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("value", ["0", "-3"])
def test_a_cell_budget_below_one_is_refused(tmp_path, capsys, value):
    code, lines = train(tmp_path, capsys, "--agent", "avq", "--set", f"max_cells={value}")
    assert code == 2 and lines == [f"avq: error: max_cells must be an integer >= 1, not {value}"]
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("value", "told"),
    [
        (
            "scale_factor=[3,3]",
            "scale_factor must be a number or 4 numbers (one per observation dimension), not [3, 3]",
        ),
        ("scale_factor=[1,0,1,1]", "scale_factor must be finite and > 0; dimension 1 has 0.0"),
    ],
)
def test_a_bad_scale_factor_is_refused_from_the_command_line(tmp_path, capsys, value, told):
    code, lines = train(tmp_path, capsys, "--agent", "avq", "--set", value)
    assert code == 2 and lines == [f"avq: error: {told}"]
    assert not (tmp_path / "run").exists()


@pytest.fixture
def nan_env():
    """Registers NAN_ENV, whose fifth episode has a NaN at its third step."""
    gym.register(NAN_ENV, entry_point=lambda: NaNAt(CartPoleEnv(), episode=5, step=3), max_episode_steps=500)
    yield NAN_ENV
    del gym.registry[NAN_ENV]


@pytest.mark.parametrize(
    ("every", "kept"),
    [
        (2, "its checkpoint after episode 4 and progress.csv up to it are intact"),
        (10, "it had no checkpoint yet (the first comes after episode 10)"),
    ],
)
def test_a_nan_observation_names_step_and_episode_and_keeps_what_was_written(tmp_path, capsys, nan_env, every, kept):
    out = tmp_path / "run"
    code = main(
        [
            "train",
            "--env",
            nan_env,
            "--agent",
            "avq",
            "--episodes",
            "20",
            "--checkpoint-every",
            str(every),
            "--no-progress",
            "--out",
            str(out),
        ]
    )
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert "at step 3 of episode 5 is not finite" in lines[0]
    assert lines[0].endswith(
        f"; the run in {out} stopped there: {kept}; once the environment is fixed, continue "
        f"it with 'avq train --resume {out}'"
    )
    assert not (out / "model.zip").exists() and (out / "config.yml").exists()
    if every == 10:
        assert not (out / "checkpoint.zip").exists()
        return
    agent = avq.load(out / "checkpoint.zip")
    assert agent.num_episodes == 4
    with open(out / "progress.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["return"]) for r in rows] == agent.episode_history()["return"].tolist()
