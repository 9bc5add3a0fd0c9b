"""benchmarks/optimism.py: each configuration's run as set, and one tiny run of the script."""

import csv
import importlib.util
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SPEC = importlib.util.spec_from_file_location("optimism", ROOT / "benchmarks" / "optimism.py")
optimism = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(optimism)


def test_a_random_run_is_the_seeded_random_policy_and_its_final_return_the_mean_of_the_last_episodes():
    row = optimism.run("CartPole-v1", "random", "", 3, 4)
    env = gym.make("CartPole-v1")
    env.action_space.seed(3)
    returns, steps = [], 0
    for e in range(4):
        env.reset(seed=300_000 + e)
        done, total = False, 0.0
        while not done:
            _, r, term, trunc, _ = env.step(env.action_space.sample())
            total, done, steps = total + r, term or trunc, steps + 1
        returns.append(total)
    assert row["final_return"] == round(float(np.mean(returns)), 1) and row["env_steps"] == steps
    assert row == optimism.run("CartPole-v1", "random", "", 3, 4) | {"wall_s": row["wall_s"]}


def test_avq_runs_with_the_v_opt_given_and_auto_follows_the_rewards():
    fixed = optimism.run("CartPole-v1", "avq", 7.0, 0, 3)
    assert fixed["v_opt"] == 7.0 and fixed["v_opt_end"] == 7.0 and fixed["cells"] >= 1
    auto = optimism.run("CartPole-v1", "avq", "auto", 0, 3)
    assert auto["v_opt_end"] == 500.0  # (the time limit, 500, times the largest reward, 1)


def test_the_script_writes_a_row_per_configuration_and_seed(tmp_path):
    cmd = [sys.executable, str(ROOT / "benchmarks" / "optimism.py"), "--tasks", "CartPole-v1", "--seeds", "0-1"]
    cmd += ["--v-opt", "auto", "0", "--baselines", "random", "--episodes", "2", "--jobs", "1", "--out", str(tmp_path)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd=ROOT).stdout
    rows = list(csv.DictReader((tmp_path / "optimism_seeds0-1.csv").open()))
    assert [(r["agent"], r["v_opt"], r["seed"]) for r in rows] == [
        ("avq", "auto", "0"), ("avq", "auto", "1"), ("avq", "0.0", "0"), ("avq", "0.0", "1"),
        ("random", "", "0"), ("random", "", "1"),
    ]  # fmt: skip
    assert "| CartPole-v1 | avq | auto |" in out and "| CartPole-v1 | random |" in out
    # A run of some configurations again replaces their rows and keeps the others (the baselines', "auto"'s).
    before = {(r["agent"], r["v_opt"], r["seed"]): r for r in rows}
    again = cmd[: cmd.index("--v-opt")] + ["--v-opt", "0", "--baselines", "--episodes", "3", "--jobs", "1"]
    subprocess.run(again + ["--out", str(tmp_path)], capture_output=True, text=True, check=True, cwd=ROOT)
    after = {
        (r["agent"], r["v_opt"], r["seed"]): r for r in csv.DictReader((tmp_path / "optimism_seeds0-1.csv").open())
    }
    assert sorted(after) == sorted(before)  # (no row lost, none twice)
    assert after[("avq", "0.0", "0")]["episodes"] == "3" and after[("avq", "auto", "0")]["episodes"] == "2"
    assert after[("random", "", "1")] == before[("random", "", "1")]


def test_axis_share_goes_to_avq_and_names_the_file(tmp_path):
    # Every outcome split of these 10 episodes cuts across one axis (share 0): other cells than without it.
    row = optimism.run("CartPole-v1", "avq", "auto", 0, 10, axis_share=0.0)
    plain = optimism.run("CartPole-v1", "avq", "auto", 0, 10)
    assert row["axis_share"] == 0.0 and "axis_share" not in plain
    assert (row["cells"], row["env_steps"]) != (plain["cells"], plain["env_steps"])
    assert row | {"wall_s": 0} == optimism.run("CartPole-v1", "avq", "auto", 0, 10, axis_share=0.0) | {"wall_s": 0}
    cmd = [sys.executable, str(ROOT / "benchmarks" / "optimism.py"), "--tasks", "CartPole-v1", "--seeds", "0-0"]
    cmd += ["--v-opt", "auto", "--baselines", "--episodes", "2", "--axis-share", "0.8", "--jobs", "1"]
    subprocess.run(cmd + ["--out", str(tmp_path)], capture_output=True, text=True, check=True, cwd=ROOT)
    rows = list(csv.DictReader((tmp_path / "optimism_seeds0-0_axis0.8.csv").open()))
    assert [(r["agent"], r["axis_share"]) for r in rows] == [("avq", "0.8")]
