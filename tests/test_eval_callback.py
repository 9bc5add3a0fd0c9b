"""``EvalCallback``: the greedy policy evaluated every ``every`` episodes on an environment of its own, the rows
written to ``evaluations.csv`` and the best agent to ``best.zip``, without changing what the agent learns."""

import csv

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq import EvalCallback, evaluate_policy


@pytest.mark.parametrize(
    "name, env_id, extra",
    [("avq", "MountainCar-v0", {}), ("avq-paper", "avq/GridMaze-v0", {}), ("tiles", "MountainCar-v0", {})],
)
def test_learning_with_evaluations_gives_the_same_agent(tmp_path, name, env_id, extra):
    # (avq-paper on the grid maze learns in a compiled loop, which the callback stops every `every` episodes)
    plain = avq.make_agent(name, gym.make(env_id), seed=4, **extra).learn(total_episodes=12)
    watched = avq.make_agent(name, gym.make(env_id), seed=4, **extra)
    cb = EvalCallback(gym.make(env_id), every=4, n_eval_episodes=2, directory=tmp_path)
    watched.learn(total_episodes=12, callback=cb)
    assert [h["return"] for h in watched.history_] == [h["return"] for h in plain.history_]
    assert watched.num_timesteps == plain.num_timesteps
    obs, _ = gym.make(env_id).reset(seed=9)
    assert np.array_equal(watched.predict(obs)[0], plain.predict(obs)[0])
    assert [r["episode"] for r in cb.evaluations_] == [4, 8, 12]


def test_each_row_is_the_greedy_policy_evaluated_then_and_the_best_agent_is_saved(tmp_path):
    env_id = "CartPole-v1"
    agent = avq.make_agent("avq", gym.make(env_id), seed=0)
    cb = EvalCallback(gym.make(env_id), every=5, n_eval_episodes=3, directory=tmp_path, seed=7)
    expected = []
    for _ in range(4):  # the same evaluations made by hand after every 5 episodes
        agent.learn(total_episodes=5, callback=cb)
        expected.append(evaluate_policy(agent, gym.make(env_id), 3, seed=7)["mean_return"])
    means = [r["mean_return"] for r in cb.evaluations_]
    assert means == expected
    assert [r["timesteps"] for r in cb.evaluations_][-1] == agent.num_timesteps
    assert cb.best_mean_return_ == max(means)
    assert len(set(means)) > 1  # (else "the best" would say nothing)

    rows = list(csv.DictReader((tmp_path / "evaluations.csv").open()))
    assert [int(r["episode"]) for r in rows] == [5, 10, 15, 20]
    assert [float(r["mean_return"]) for r in rows] == means
    assert rows[0]["success_rate"] != ""  # (CartPole defines success: lasting until the time limit)
    best = avq.load(tmp_path / "best.zip", env=gym.make(env_id))
    assert best.num_episodes == 5 * (int(np.argmax(means)) + 1)  # the first evaluation with the best mean
    assert evaluate_policy(best, gym.make(env_id), 3, seed=7)["mean_return"] == max(means)


def test_without_a_directory_nothing_is_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cb = EvalCallback(gym.make("MountainCar-v0"), every=1, n_eval_episodes=1)
    avq.make_agent("avq", gym.make("MountainCar-v0"), seed=0).learn(total_episodes=2, callback=cb)
    assert len(cb.evaluations_) == 2 and cb.evaluations_[0]["success_rate"] is not None
    assert list(tmp_path.iterdir()) == []


def test_bad_arguments_get_clear_errors(tmp_path):
    env = gym.make("MountainCar-v0")
    with pytest.raises(ValueError, match="eval every"):
        EvalCallback(env, every=0)
    with pytest.raises(ValueError, match="n_eval_episodes"):
        EvalCallback(env, every=1, n_eval_episodes=0)
    with pytest.raises(TypeError, match="gymnasium environment, not str"):
        EvalCallback("MountainCar-v0", every=1)
    (tmp_path / "f").write_text("x")
    with pytest.raises(ValueError, match="is a file; give a directory"):
        EvalCallback(env, every=1, directory=tmp_path / "f")
    agent = avq.make_agent("avq", env, seed=0)
    with pytest.raises(ValueError, match="one of its own"):
        agent.learn(total_episodes=1, callback=EvalCallback(env, every=1))
    with pytest.raises(ValueError, match="EvalCallback"):  # other spaces than the agent's
        agent.learn(total_episodes=1, callback=EvalCallback(gym.make("CartPole-v1"), every=1))
    assert agent.num_episodes == 0


def test_a_directory_holding_an_earlier_runs_evaluations_is_refused_and_kept(tmp_path):
    env_id = "MountainCar-v0"
    first = EvalCallback(gym.make(env_id), every=1, n_eval_episodes=1, directory=tmp_path)
    avq.make_agent("avq", gym.make(env_id), seed=0).learn(total_episodes=3, callback=first)
    written = {name: (tmp_path / name).read_bytes() for name in ("evaluations.csv", "best.zip")}
    with pytest.raises(ValueError) as caught:
        EvalCallback(gym.make(env_id), every=1, directory=tmp_path)
    assert str(caught.value) == (
        f"eval directory {tmp_path} holds evaluations.csv and best.zip already (an earlier run's, which this one "
        "would replace); give another directory, or move them away to start again"
    )
    assert {name: (tmp_path / name).read_bytes() for name in written} == written
    (tmp_path / "evaluations.csv").unlink()
    with pytest.raises(ValueError, match="holds best.zip already"):
        EvalCallback(gym.make(env_id), every=1, directory=tmp_path)


def test_evaluate_policy_takes_an_id_and_names_a_task_or_a_seed_that_does_not_fit():
    agent = avq.make_agent("avq", gym.make("MountainCar-v0"), seed=0).learn(total_episodes=2)
    by_id = evaluate_policy(agent, "MountainCar-v0", 2, seed=3)
    assert by_id["returns"] == evaluate_policy(agent, gym.make("MountainCar-v0"), 2, seed=3)["returns"]
    with pytest.raises(ValueError, match="evaluate_policy: the agent was trained on MountainCar-v0 with"):
        evaluate_policy(agent, "CartPole-v1", 1)
    with pytest.raises(ValueError, match="seed must be an integer >= 0, not -1"):
        evaluate_policy(agent, "MountainCar-v0", 1, seed=-1)
    with pytest.raises(ValueError, match="unknown environment 'NoSuchTask-v0'"):
        evaluate_policy(agent, "NoSuchTask-v0", 1)


def test_evaluating_on_the_env_being_learned_on_warns_between_episodes_and_is_refused_inside_one():
    env = gym.make("MountainCar-v0")
    agent = avq.make_agent("avq", env, seed=0).learn(total_episodes=1)
    with pytest.warns(UserWarning, match="the environment the agent learns on: its resets change the starts"):
        evaluate_policy(agent, env, 1)
    agent.learn(total_timesteps=50)  # (stops inside an episode: MountainCar's last 200 steps)
    assert agent.in_episode
    for same in (env, env.unwrapped):  # (wrappers aside, one environment)
        with pytest.raises(ValueError, match="the agent is learning an episode on; give it one of its own"):
            evaluate_policy(agent, same, 1)
    with pytest.raises(ValueError, match="one of its own"):
        agent.learn(total_episodes=1, callback=EvalCallback(env.unwrapped, every=1))
