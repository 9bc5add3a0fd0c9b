"""``max_repeat``: a decision ends after at most that many steps, even in the same cell, and is then learned as
any other aggregate transition (SPEC §2 and §5, beyond the paper). Situations built by hand, numbers written out."""

import re

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq import AVQSarsa
from avq.cli import main

from conftest import ScriptedEnv

NO = False


def one_action_agent(steps, **kw):
    """An agent with one action on a 1-D scripted episode (so that every decision is known)."""
    params = dict(
        alpha=0.5, lam=0.7, gamma=0.5, epsilon=0.0, d_min=1.0, rho=0.0, q_init=0.0, merge_every=0, scale=1.0, seed=0
    )
    params.update(kw)
    return AVQSarsa(ScriptedEnv([((0.0,), steps)], n_actions=1, dims=1), **params)


#: Seven steps of reward 1 that never leave x = 0 (one cell); the seventh ends the episode.
STAY = [((0.0,), 1.0, k == 6, NO, NO) for k in range(7)]


def test_max_repeat_ends_a_decision_every_n_steps_in_the_same_cell():
    # gamma 0.5, alpha 0.5, one action. Decisions of 3, 3 and 1 steps:
    #   1: R = 1 + 0.5 + 0.25 = 1.75, gamma^3 = 0.125, delta = 1.75 + 0.125 * 0 - 0 = 1.75,           Q = 0.875
    #   2: R = 1.75, delta = 1.75 + 0.125 * 0.875 - 0.875 = 0.984375,                                   Q = 1.3671875
    #   3: terminal, R = 1, delta = 1 - 1.3671875 = -0.3671875,                                          Q = 1.18359375
    # (one state-action pair: its replacing trace is 1 at every update)
    agent = one_action_agent(STAY, max_repeat=3)
    agent.learn(total_episodes=1)
    assert agent.q_.tolist() == [[1.18359375]]
    assert agent.history_[0]["decisions"] == 3 and agent.history_[0]["steps"] == 7


def test_without_max_repeat_the_decision_lasts_until_the_episode_ends():
    # One decision of 7 steps: R = 1 + 0.5 + ... + 0.5^6 = 1.984375, terminal, Q = 0.5 * 1.984375.
    agent = one_action_agent(STAY, max_repeat=None)
    agent.learn(total_episodes=1)
    assert agent.q_.tolist() == [[0.9921875]]
    assert agent.history_[0]["decisions"] == 1


def test_a_decision_ended_by_max_repeat_grows_cells_as_any_other():
    # x = 0, 0.1, ..., 0.7 (scale 1, d_min 0.05), lambda 0.5, value_trigger 1. Decision 1 ends after 3 steps at
    # x = 0.3 in cell 0: delta = 1.75 (as above) >= 1, so 0.3 is appended as a copy of Q[0] = 0.875.
    # Decision 2 (cell 1, x = 0.4-0.6 nearest 0.3): delta = 1.75 + 0.125 * 0.875 - 0.875 = 0.984375 < 1;
    #   Q[1] = 0.875 + 0.5 * 0.984375 = 1.3671875; cell 0's trace 0.125 * 0.5 = 0.0625:
    #   Q[0] = 0.875 + 0.5 * 0.984375 * 0.0625 = 0.90576171875.
    # Decision 3 (terminal at 0.7, cell 1): delta = 1 - 1.3671875 = -0.3671875; Q[1] = 1.18359375;
    #   cell 0's trace 0.0625 * 0.0625: Q[0] = 0.90576171875 - 0.5 * 0.3671875 / 256 = 0.9050445556640625.
    steps = [((0.1 * (k + 1),), 1.0, k == 6, NO, NO) for k in range(7)]
    agent = one_action_agent(steps, max_repeat=3, lam=0.5, d_min=0.05, value_trigger=1.0)
    agent.learn(total_episodes=1)
    assert agent.codebook_.tolist() == [[0.0], [0.30000000000000004]]
    assert agent.q_.tolist() == [[0.9050445556640625], [1.18359375]]
    assert (agent.history_[0]["appends"], agent.history_[0]["decisions"]) == (1, 3)


def test_the_count_goes_on_across_learn_calls_and_a_saved_agent_resumes_exactly(tmp_path):
    def make():
        return avq.make_agent("avq-sarsa", gym.make("CartPole-v1"), seed=3, max_repeat=2)

    straight = make().learn(total_episodes=12)
    split = make().learn(total_timesteps=41).learn(total_timesteps=33)  # stops inside decisions
    split.learn(total_episodes=12 - split.num_episodes - 1)
    split.save(tmp_path / "m.zip")
    resumed = avq.load(tmp_path / "m.zip")
    assert resumed.get_params()["max_repeat"] == 2
    resumed.learn(total_episodes=1)
    for key in ("steps", "return", "n_cells", "decisions"):
        assert np.array_equal(resumed.episode_history()[key], straight.episode_history()[key]), key
    assert np.array_equal(resumed.q_, straight.q_) and np.array_equal(resumed.codebook_, straight.codebook_)
    # The option acts: decisions are at least half the steps, which one decision per cell never is here.
    h = straight.episode_history()
    assert (2 * h["decisions"] >= h["steps"]).all()
    unbounded = avq.make_agent("avq-sarsa", gym.make("CartPole-v1"), seed=3, max_repeat=None).learn(total_episodes=12)
    assert (2 * unbounded.episode_history()["decisions"] < unbounded.episode_history()["steps"]).any()


def same(a, b):
    assert np.array_equal(a.codebook_, b.codebook_) and np.array_equal(a.q_, b.q_)
    ha, hb = a.episode_history(), b.episode_history()
    for key in ("steps", "return", "n_cells", "appends", "merges", "refused", "decisions"):
        assert np.array_equal(ha[key], hb[key]), key


@pytest.mark.parametrize("name", ["avq-maze", "avq-paper"])
def test_the_fused_maze_loop_and_the_generic_path_agree_with_max_repeat(name):
    def run(fused, max_repeat):
        agent = avq.make_agent(name, gym.make("avq/GridMaze-v0"), seed=1, fused=fused, max_repeat=max_repeat)
        return agent.learn(total_episodes=150)

    fused = run(True, 2)
    same(fused, run(False, 2))
    # and the option changed what was learned
    assert fused.episode_history()["decisions"].sum() > run(True, None).episode_history()["decisions"].sum()


@pytest.mark.parametrize("value", [0, -3, 2.5, True, "3"])
def test_max_repeat_must_be_a_positive_integer_or_none(value):
    with pytest.raises(
        ValueError, match=f"^{re.escape(f'max_repeat must be an integer >= 1 or None, not {value!r}')}$"
    ):
        avq.make_agent("avq-sarsa", gym.make("CartPole-v1"), max_repeat=value)


def test_the_command_line_names_a_bad_max_repeat_and_takes_null(tmp_path, capsys):
    args = ["train", "--env", "CartPole-v1", "--agent", "avq-sarsa", "--episodes", "2", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "bad"), "--set", "max_repeat=0"]) == 2
    assert capsys.readouterr().err.strip() == "avq: error: max_repeat must be an integer >= 1 or None, not 0"
    assert not (tmp_path / "bad").exists()
    assert main([*args, "--out", str(tmp_path / "ok"), "--set", "max_repeat=null"]) == 0
    assert avq.load(tmp_path / "ok" / "model.zip").max_repeat is None
    # Python's spelling, as the error message writes it, is read as null too.
    assert main([*args, "--out", str(tmp_path / "py"), "--set", "max_repeat=None"]) == 0
    assert avq.load(tmp_path / "py" / "model.zip").max_repeat is None
