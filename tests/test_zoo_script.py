"""benchmarks/zoo.py: every agent on the same env steps, its greedy policy checked after each chunk."""

import csv
import importlib.util
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import avq
from avq.evaluation import evaluate_policy

ROOT = Path(__file__).resolve().parents[1]
SPEC = importlib.util.spec_from_file_location("zoo", ROOT / "benchmarks" / "zoo.py")
zoo = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(zoo)


def test_the_threshold_is_reached_at_the_first_check_whose_greedy_mean_reaches_it():
    steps, means = [100, 200, 300, 400], [-150.0, -110.0, -120.0, -90.0]
    assert zoo.first_reaching(steps, means, -110.0) == 200  # (reaching counts: -110 >= -110)
    assert zoo.first_reaching(steps, means, -100.0) == 400
    assert zoo.first_reaching(steps, means, -50.0) is None


def test_avq_learns_the_budget_exactly_and_its_last_check_is_the_greedy_policy_after_it():
    row = zoo.run("avq", "CartPole-v1", 0, 1_000)
    assert row["env_steps"] == 1_000 and row["budget"] == 1_000 and row["threshold"] == 475.0
    # learn(a) then learn(b) is learn(a + b): the agent of the last check is this one.
    agent = avq.PlanningAVQ(gym.make("CartPole-v1"), seed=0).learn(total_timesteps=1_000)
    ev = evaluate_policy(agent, gym.make("CartPole-v1"), n_eval_episodes=zoo.CHECK_EPISODES, seed=10_000)
    assert row["greedy_return"] == round(ev["mean_return"], 1) and row["best_greedy"] >= row["greedy_return"]
    returns = agent.episode_history()["return"]
    assert row["final_return"] == round(float(np.mean(returns[-zoo.TAIL :])), 1)
    assert row["cells"] == agent.n_cells and row["episodes"] == len(returns)
    assert row | {"wall_s": 0, "steps_per_s": 0} == zoo.run("avq", "CartPole-v1", 0, 1_000) | {
        "wall_s": 0,
        "steps_per_s": 0,
    }


def test_the_general_entry_and_the_per_task_entry_are_different_agents_where_the_task_has_one():
    assert zoo.has_entry("CartPole-v1") and zoo.has_entry("Acrobot-v1")
    assert not zoo.has_entry("MountainCar-v0") and not zoo.has_entry("LunarLander-v3")
    env = gym.make("CartPole-v1")
    general, entry = zoo.make("avq", env, "CartPole-v1", 0, 100), zoo.make("avq-entry", env, "CartPole-v1", 0, 100)
    assert general.get_params() == avq.PlanningAVQ(env).get_params() | {"seed": 0}
    assert entry.get_params() != general.get_params()
    # tiles gets benchmarks/compare.py's settings for the task (a box for CartPole's unbounded velocities).
    assert (
        zoo.make("tiles", env, "CartPole-v1", 0, 100).get_params()["obs_bounds"]
        == zoo.COMPARE_TASKS["CartPole-v1"][2]["tiles"]["obs_bounds"]
    )


def test_rows_written_again_replace_those_of_the_same_run_and_keep_the_others(tmp_path):
    path, fields = tmp_path / "zoo.csv", ("task", "agent", "seed", "greedy_return")
    first = [{"task": "CartPole-v1", "agent": "avq", "seed": s, "greedy_return": 1.5} for s in (10, 11)]
    zoo.write_csv(path, fields, first, ("task", "agent", "seed"))
    again = [{"task": "CartPole-v1", "agent": "avq", "seed": 11, "greedy_return": 2.5}]
    rows = zoo.write_csv(path, fields, again, ("task", "agent", "seed"))
    assert [(r["seed"], r["greedy_return"]) for r in rows] == [(10, 1.5), (11, 2.5)]


def test_random_plays_seeded_episodes_until_the_budget():
    row = zoo.run("random", "CartPole-v1", 3, 200)
    policy = zoo.RandomPolicy(gym.make("CartPole-v1").action_space, 3)
    env, returns, steps = gym.make("CartPole-v1"), [], 0
    while steps < 200:
        ep = evaluate_policy(policy, env, n_eval_episodes=1, seed=300_000 + len(returns))
        returns.append(ep["returns"][0])
        steps += ep["steps"][0]
    assert row["env_steps"] == steps and row["episodes"] == len(returns) and row["cells"] == 0
    assert row["final_return"] == round(float(np.mean(returns)), 1)


def test_the_script_writes_a_row_per_run_and_refuses_unknown_names(tmp_path):
    script = str(ROOT / "benchmarks" / "zoo.py")
    cmd = [sys.executable, script, "--quick", "--tasks", "MountainCar-v0", "--agents", "avq-entry,random"]
    out = subprocess.run(
        [*cmd, "--seeds", "0-1", "--jobs", "1", "--out", str(tmp_path)], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader((tmp_path / "zoo.csv").open()))
    # (MountainCar has no entry of avq's own: avq-entry would be avq, not run)
    assert [(r["task"], r["agent"], r["seed"], r["budget"]) for r in rows] == [
        ("MountainCar-v0", "random", "0", "6000"), ("MountainCar-v0", "random", "1", "6000"),
    ]  # fmt: skip
    assert "| MountainCar-v0 | 0 | random |" in out.stdout
    bad = subprocess.run(
        [sys.executable, script, "--tasks", "Pong", "--out", str(tmp_path)], capture_output=True, text=True
    )
    assert bad.returncode == 2 and "--tasks Pong: choose from MountainCar-v0" in bad.stderr
    bad = subprocess.run(
        [sys.executable, script, "--agents", "ppo", "--out", str(tmp_path)], capture_output=True, text=True
    )
    assert bad.returncode == 2 and "--agents ppo: choose from avq, avq-entry" in bad.stderr


def test_times_multiplies_the_budgets_and_keeps_docs_data_at_the_zoos(tmp_path):
    script = str(ROOT / "benchmarks" / "zoo.py")
    cmd = [sys.executable, script, "--quick", "--tasks", "MountainCar-v0", "--agents", "random", "--seeds", "0-0"]
    out = subprocess.run(
        [*cmd, "--times", "2.5", "--jobs", "1", "--out", str(tmp_path)], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader((tmp_path / "zoo.csv").open()))
    assert [(r["budget"], r["env_steps"]) for r in rows] == [("15000", "15000")]  # (120,000 x 2.5 / 20)
    for times, message in [("0", "--times 0.0: give a multiple"), ("-1", "--times -1.0: give a multiple")]:
        bad = subprocess.run([*cmd, "--times", times, "--out", str(tmp_path)], capture_output=True, text=True)
        assert bad.returncode == 2 and message in bad.stderr
    before = (ROOT / "docs" / "data" / "zoo.csv").read_bytes()
    bad = subprocess.run(
        [sys.executable, script, "--times", "10", "--agents", "random"], capture_output=True, text=True, cwd=ROOT
    )
    assert bad.returncode == 2 and "--times changes the budgets: write it elsewhere than docs/data" in bad.stderr
    assert (ROOT / "docs" / "data" / "zoo.csv").read_bytes() == before


def test_plot_draws_the_csv_and_says_what_to_run_without_one(tmp_path):
    script, data = str(ROOT / "benchmarks" / "zoo.py"), tmp_path / "data"
    rows = [
        {"task": t, "agent": a, "seed": s, "budget": 1000, "threshold": 475.0, "greedy_return": 100.0 * s,
         "steps_to_threshold": 500 if a == "avq" else None}
        for t in ("CartPole-v1", "Acrobot-v1") for a in ("avq", "tiles", "random") for s in (0, 1)
    ]  # fmt: skip
    zoo.plot([r | {"noise": 0} for r in rows], tmp_path / "figures" / "zoo.png")
    assert (tmp_path / "figures" / "zoo.png").stat().st_size > 10_000
    out = subprocess.run([sys.executable, script, "--plot", "--out", str(data)], capture_output=True, text=True)
    assert out.returncode == 2 and f"--plot: no {data / 'zoo.csv'}; run the study first" in out.stderr


def test_with_noise_every_agent_sees_the_appended_dimensions_and_tiles_bounds_cover_them():
    row = zoo.run("avq", "CartPole-v1", 0, 1_000, noise=2)
    assert row["noise"] == 2 and row["env_steps"] == 1_000
    agent = avq.PlanningAVQ(avq.envs.IrrelevantDims(gym.make("CartPole-v1"), 2), seed=0).learn(total_timesteps=1_000)
    ev = evaluate_policy(
        agent, avq.envs.IrrelevantDims(gym.make("CartPole-v1"), 2), n_eval_episodes=zoo.CHECK_EPISODES, seed=10_000
    )
    assert row["greedy_return"] == round(ev["mean_return"], 1) and row["cells"] == agent.n_cells
    tiles = zoo.make("tiles", zoo.make_env("CartPole-v1", 2), "CartPole-v1", 0, 100, noise=2)
    bounds = zoo.COMPARE_TASKS["CartPole-v1"][2]["tiles"]["obs_bounds"]
    assert tiles.get_params()["obs_bounds"] == [*bounds, [0.0, 1.0], [0.0, 1.0]]
    assert zoo.make_env("CartPole-v1", 0).observation_space.shape == (4,)


def test_the_script_with_noise_records_it_skips_the_per_task_entry_and_refuses_a_negative_count(tmp_path):
    script = str(ROOT / "benchmarks" / "zoo.py")
    cmd = [sys.executable, script, "--quick", "--tasks", "CartPole-v1", "--agents", "avq-entry,random", "--seeds", "0"]
    out = subprocess.run(
        [*cmd, "--noise", "2", "--jobs", "1", "--out", str(tmp_path / "data")], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader((tmp_path / "data" / "zoo.csv").open()))
    # (a wrapped task gets the general defaults: avq-entry would be avq, not run)
    assert [(r["task"], r["noise"], r["agent"]) for r in rows] == [("CartPole-v1", "2", "random")]
    assert "| CartPole-v1 | 2 | random |" in out.stdout
    assert (tmp_path / "figures" / "zoo_noise2.png").exists() and not (tmp_path / "figures" / "zoo.png").exists()
    bad = subprocess.run([*cmd, "--noise", "-1", "--out", str(tmp_path / "data")], capture_output=True, text=True)
    assert bad.returncode == 2 and "--noise -1: give a count of noise dimensions, 0 or more" in bad.stderr


def test_set_makes_a_variant_of_avq_and_refuses_what_avq_would(tmp_path):
    row = zoo.run("avq", "CartPole-v1", 0, 1_000, params={"compose_crossings": True})
    agent = avq.PlanningAVQ(gym.make("CartPole-v1"), seed=0, compose_crossings=True).learn(total_timesteps=1_000)
    ev = evaluate_policy(agent, gym.make("CartPole-v1"), n_eval_episodes=zoo.CHECK_EPISODES, seed=10_000)
    assert row["greedy_return"] == round(ev["mean_return"], 1) and row["cells"] == agent.n_cells
    entry = zoo.make("avq-entry", gym.make("CartPole-v1"), "CartPole-v1", 0, 100, params={"compose_crossings": True})
    assert entry.compose_crossings and entry.epsilon == 0.01  # (CartPole's own entry, with the variant's parameter)
    script = str(ROOT / "benchmarks" / "zoo.py")
    cmd = [sys.executable, script, "--quick", "--tasks", "CartPole-v1", "--seeds", "0", "--jobs", "1"]
    out = subprocess.run(
        [*cmd, "--agents", "avq,random", "--set", "compose_crossings=true", "--out", str(tmp_path / "data")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader((tmp_path / "data" / "zoo.csv").open()))
    assert [r["agent"] for r in rows] == ["avq", "random"] and not (tmp_path / "figures").exists()
    for args, message in [
        (["--agents", "avq", "--set", "nope=1"], "--set nope=1: avq refuses it"),
        (["--agents", "avq", "--set", "compose_crossings=1"], "compose_crossings must be True, False or 'noise'"),
        (["--agents", "avq", "--set", "compose_crossings"], "--set compose_crossings: give KEY=VALUE"),
        (["--agents", "tiles", "--set", "compose_crossings=true"], "--agents names neither"),
    ]:
        bad = subprocess.run([*cmd, *args, "--out", str(tmp_path / "x")], capture_output=True, text=True)
        assert bad.returncode == 2 and message in bad.stderr, bad.stderr
    bad = subprocess.run([*cmd, "--agents", "avq", "--set", "compose_crossings=true"], capture_output=True, text=True)
    assert bad.returncode == 2 and "--set makes a variant: write it elsewhere than docs/data" in bad.stderr
    assert not (tmp_path / "x").exists()
