"""`avq train` and `avq evaluate` end to end, and their answers to mistakes."""

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

import avq
from avq.cli import main

from conftest import CLI_RUNNERS


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "avq.cli", *args], capture_output=True, text=True, cwd=cwd)


def test_train_writes_the_run_directory_and_evaluate_reads_it(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(
        [
            "train",
            "--env",
            "avq/GridMaze-v0",
            "--agent",
            "avq-paper",
            "--episodes",
            "30",
            "--seed",
            "3",
            "--out",
            str(out),
            "--set",
            "alpha=0.3",
            "--set",
            "epsilon=0.1",
            "--env-kwargs",
            "start=fixed",
            "--no-progress",
        ]
    )
    assert code == 0
    assert "avq-paper on avq/GridMaze-v0 (seed 3): 30 episodes" in capsys.readouterr().out
    config = yaml.safe_load((out / "config.yml").read_text())
    assert config["env"] == "avq/GridMaze-v0" and config["env_kwargs"] == {"start": "fixed"}
    assert config["agent"] == "avq-paper" and config["seed"] == 3 and config["episodes"] == 30
    assert config["params"]["alpha"] == 0.3 and config["params"]["epsilon"] == 0.1
    with open(out / "progress.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 30
    assert set(rows[0]) >= {"episode", "steps", "return", "n_cells", "wall_s"}
    assert [int(r["episode"]) for r in rows] == list(range(1, 31))
    model = avq.load(out / "model.zip")
    assert model.num_episodes == 30 and model.n_cells == int(rows[-1]["n_cells"])
    assert sum(int(r["steps"]) for r in rows) == model.num_timesteps
    summary = json.loads((out / "summary.json").read_text())
    assert summary["episodes"] == 30 and summary["env_steps"] == model.num_timesteps

    assert main(["evaluate", str(out), "--episodes", "3", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["episodes"] == 3 and report["n_cells"] == model.n_cells
    assert 0.0 <= report["success_rate"] <= 1.0 and 0.0 <= report["maze_success_rate"] <= 1.0
    assert main(["evaluate", str(out)]) == 0
    assert "return" in capsys.readouterr().out


def test_train_says_which_defaults_it_took(tmp_path, capsys):
    assert (
        main(["train", "--env", "avq/GridMaze-v0", "--episodes", "3", "--out", str(tmp_path / "maze"), "--no-progress"])
        == 0
    )
    assert capsys.readouterr().out.splitlines()[0] == (
        "agent avq on avq/GridMaze-v0: the avq/GridMaze-v0 defaults of avq "
        "(avq/agents/defaults/avq.yaml, entry 'avq/GridMaze-v0'); explicit: none"
    )
    assert (
        main(
            [
                "train",
                "--env",
                "MountainCar-v0",
                "--timesteps",
                "250",
                "--set",
                "d_min=0.2",
                "--out",
                str(tmp_path / "car"),
                "--no-progress",
            ]
        )
        == 0
    )
    assert capsys.readouterr().out.splitlines()[0] == (
        "agent avq on MountainCar-v0: the general defaults of avq (avq/agents/defaults/avq.yaml, entry '*'); "
        "explicit: d_min=0.2"
    )
    # A parameter of the Sarsa(λ) agents is refused for the planner, naming the parameters it has.
    assert (
        main(
            [
                "train",
                "--env",
                "MountainCar-v0",
                "--timesteps",
                "250",
                "--set",
                "alpha=0.2",
                "--out",
                str(tmp_path / "bad"),
                "--no-progress",
            ]
        )
        == 2
    )
    assert capsys.readouterr().err.startswith(
        "avq: error: unknown parameter 'alpha' for agent 'avq'; its parameters: axis_share, collision_cut, collision_growth, "
    )


def test_rerunning_from_config_gives_the_same_model(tmp_path):
    first = tmp_path / "a"
    assert (
        main(
            [
                "train",
                "--env",
                "avq/GridMaze-v0",
                "--agent",
                "avq-paper",
                "--episodes",
                "20",
                "--out",
                str(first),
                "--set",
                "d_min=1.5",
                "--no-progress",
            ]
        )
        == 0
    )
    second = tmp_path / "b"
    assert main(["train", "--config", str(first / "config.yml"), "--out", str(second), "--no-progress"]) == 0
    a, b = avq.load(first / "model.zip"), avq.load(second / "model.zip")
    assert np.array_equal(a.codebook_, b.codebook_) and np.array_equal(a.q_, b.q_)


def test_train_with_timesteps_and_a_gymnasium_task(tmp_path):
    out = tmp_path / "mc"
    assert (
        main(
            [
                "train",
                "--env",
                "MountainCar-v0",
                "--agent",
                "avq-paper",
                "--timesteps",
                "450",
                "--out",
                str(out),
                "--env-kwargs",
                "max_episode_steps=150",
                "--no-progress",
            ]
        )
        == 0
    )
    model = avq.load(out / "model.zip", env=avq.runs.make_env("MountainCar-v0", {"max_episode_steps": 150}))
    assert model.num_timesteps == 450 and model.num_episodes == 3


def test_train_refuses_to_overwrite_a_finished_run(tmp_path):
    out = tmp_path / "r"
    args = [
        "train",
        "--env",
        "avq/GridMaze-v0",
        "--agent",
        "tabular",
        "--episodes",
        "2",
        "--out",
        str(out),
        "--no-progress",
    ]
    assert main(args) == 0
    before = (out / "model.zip").read_bytes()
    proc = run_cli(*args)
    assert proc.returncode == 2 and "already holds" in proc.stderr
    assert (out / "model.zip").read_bytes() == before


@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
@pytest.mark.parametrize(
    "args,needle",
    [
        (["train", "--env", "Nope-v9"], "unknown environment 'Nope-v9'"),
        (["train", "--env", "CartPole-v1", "--agent", "bogus"], "unknown agent 'bogus'"),
        (
            ["train", "--env", "avq/GridMaze-v0", "--agent", "tabular", "--set", "alpah=0.1"],
            "unknown parameter 'alpah'",
        ),
        (["train", "--env", "avq/GridMaze-v0", "--agent", "tabular", "--set", "alpha=7"], "alpha must be in"),
        (["train", "--env", "avq/GridMaze-v0", "--set", "alpha"], "key=value"),
        (["train", "--env", "avq/GridMaze-v0", "--env-kwargs", "layout=nowhere"], "nowhere"),
        (["train", "--env", "CartPole-v1", "--env-kwargs", "foo=1"], "bad env-kwargs"),
        (["train", "--episodes", "3"], "--env is required"),
        (["train", "--env", "avq/GridMaze-v0", "--episodes", "0"], "--episodes must be >= 1"),
        (["train", "--env", "avq/GridMaze-v0", "--episodes", "3", "--timesteps", "3"], "not allowed with"),
        (["train", "--config", "missing.yml"], "cannot read config"),
        (["evaluate", "no-such-dir"], "no-such-dir: no such model file or run directory"),
        (["evaluate", "afile.txt"], "afile.txt: not a readable avq model file"),
        (["train", "--env", "avq/GridMaze-v0", "--episodes", "2", "--out", "afile.txt"], "is a file; give a directory"),
        (["reproduce", "--seeds", "1", "--trials", "2", "--out", "afile.txt"], "is a file; give a directory"),
        (["train", "--env", "Pendulum-v1", "--episodes", "2"], "use the agent 'avq-actions'"),
    ],
)
def test_train_and_evaluate_mistakes_exit_2_with_one_line(args, needle, tmp_path, run_cli):
    (tmp_path / "afile.txt").write_text("keep me")
    proc = run_cli(*args, cwd=tmp_path)
    assert (tmp_path / "afile.txt").read_text() == "keep me"
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in proc.stderr
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").rglob("model.zip"))


@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
def test_bad_config_files(tmp_path, run_cli):
    bad_key = tmp_path / "a.yml"
    bad_key.write_text("env: CartPole-v1\nagnet: tabular\n")
    proc = run_cli("train", "--config", str(bad_key))
    assert proc.returncode == 2 and "unknown key 'agnet'" in proc.stderr
    bad_yaml = tmp_path / "b.yml"
    bad_yaml.write_text("env: [unclosed\n")
    proc = run_cli("train", "--config", str(bad_yaml))
    assert proc.returncode == 2 and "not valid YAML" in proc.stderr
    bad_params = tmp_path / "c.yml"
    bad_params.write_text("env: CartPole-v1\nparams: 3\n")
    proc = run_cli("train", "--config", str(bad_params))
    assert proc.returncode == 2 and "'params' must be a mapping" in proc.stderr


@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
@pytest.mark.parametrize(
    "args,needle",
    [
        (["train", "--env", "avq/GridMaze-v0", "--set", "seed=5"], "--seed"),
        (["evaluate", "x", "--seed", "-1"], "--seed must be >= 0"),
        (["reproduce", "--seeds", "1", "--trials", "2", "--out", "afile"], "is a file; give a directory"),
    ],
)
def test_more_mistakes_exit_2(args, needle, tmp_path, run_cli):
    (tmp_path / "afile").write_text("x")
    proc = run_cli(*args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert needle in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
def test_config_values_of_the_wrong_type(tmp_path, run_cli):
    cfg = tmp_path / "c.yml"
    cfg.write_text("env: avq/GridMaze-v0\nagent: [avq]\n")
    proc = run_cli("train", "--config", str(cfg))
    assert proc.returncode == 2 and "'agent' must be a string" in proc.stderr
    cfg.write_text("env: avq/GridMaze-v0\nepisodes: -3\n")
    proc = run_cli("train", "--config", str(cfg))
    assert proc.returncode == 2 and "'episodes' must be an integer >= 1" in proc.stderr


@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
def test_resume_mistakes_exit_2_and_leave_the_run_as_it_was(tmp_path, run_cli):
    run = tmp_path / "run"
    proc = run_cli(
        "train",
        "--env",
        "avq/GridMaze-v0",
        "--agent",
        "tabular",
        "--episodes",
        "30",
        "--checkpoint-every",
        "10",
        "--out",
        str(run),
        "--no-progress",
    )
    assert proc.returncode == 0, proc.stderr
    (run / "model.zip").unlink()  # as if stopped after its last checkpoint
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.name != ".avq.lock"}  # (the lock names its holder)
    cases = [
        (["train", "--resume", str(tmp_path / "nowhere")], "no such run directory"),
        (["train", "--resume", str(run), "--episodes", "5"], "drop --episodes"),
        (["train", "--resume", str(tmp_path)], "no config.yml"),
        (["train", "--env", "avq/GridMaze-v0", "--out", str(run)], "--resume"),
        (["train", "--env", "avq/GridMaze-v0", "--checkpoint-every", "0"], "--checkpoint-every must be >= 1"),
    ]
    for args, needle in cases:
        proc = run_cli(*args, cwd=tmp_path)
        assert proc.returncode == 2, (args, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0] and "Traceback" not in proc.stderr, (args, proc.stderr)
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.name != ".avq.lock"} == before
    (run / "checkpoint.zip").write_bytes(b"garbage")
    proc = run_cli("train", "--resume", str(run))
    assert proc.returncode == 2 and "checkpoint.zip" in proc.stderr and "Traceback" not in proc.stderr


def test_the_summary_says_1_cell_not_1_cells(tmp_path, capsys):
    assert (
        main(
            [
                "train",
                "--env",
                "CartPole-v1",
                "--episodes",
                "3",
                "--seed",
                "0",
                "--set",
                "max_cells=1",
                "--out",
                str(tmp_path / "one"),
                "--no-progress",
            ]
        )
        == 0
    )
    assert ", 1 cell, mean return" in capsys.readouterr().out
