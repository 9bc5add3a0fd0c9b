"""Small mistakes and what avq says about them (issue 26, part 4): each message names the problem, the path or
value given and the fix; the command line exits 2 without a traceback, and nothing already written is lost.
Also the figures and nouns of avq's reports: seconds that are not 0.00, tiles that are not cells, one way to
name an agent, and a 95% interval over few seeds that says it is wide."""

from __future__ import annotations

import csv
import sys
import traceback

import gymnasium as gym
import pytest

import avq
from avq._io import check_output_dir
from avq.reproduce import format_table
from avq.runs import train
from avq.sweep import report

from conftest import cli_in_process


@pytest.fixture(scope="module")
def stopped_run(tmp_path_factory):
    """A tabular run on the maze, 30 episodes with checkpoints every 10, stopped after its last checkpoint (no
    model.zip, no summary.json)."""
    run = tmp_path_factory.mktemp("stopped") / "run"
    train("avq/GridMaze-v0", "tabular", episodes=30, checkpoint_every=10, out=run, progress=False)
    (run / "model.zip").unlink()
    (run / "summary.json").unlink()
    return run


def one_error_line(result) -> str:
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def test_evaluate_of_a_missing_path_says_model_file_or_run_directory(tmp_path):
    line = one_error_line(cli_in_process("evaluate", "nonexist.zip", cwd=tmp_path))
    assert line == (
        "avq: error: nonexist.zip: no such model file or run directory; give a directory written by "
        "'avq train' or a model file written by agent.save"
    )


def test_evaluate_of_a_stopped_run_points_at_its_checkpoint_which_evaluates(stopped_run):
    line = one_error_line(cli_in_process("evaluate", str(stopped_run)))
    checkpoint = stopped_run / "checkpoint.zip"
    assert f"give its last checkpoint instead, {checkpoint}, or finish" in line
    assert f"avq train --resume {stopped_run}" in line
    result = cli_in_process("evaluate", str(checkpoint), "--episodes", "2")
    assert result.returncode == 0 and result.stdout.startswith("tabular (TabularSarsa) on avq/GridMaze-v0:")
    assert one_error_line(cli_in_process("plot", str(stopped_run))) == line  # (words that fit plot too)


def test_evaluate_names_the_agent_and_its_class_for_a_run_and_for_its_model_file(tmp_path):
    run = tmp_path / "run"
    train("avq/GridMaze-v0", "tabular", episodes=5, out=run, progress=False)
    lines = [cli_in_process("evaluate", str(target), "--episodes", "2").stdout for target in (run, run / "model.zip")]
    assert all(line.startswith("tabular (TabularSarsa) on avq/GridMaze-v0: return") for line in lines), lines
    # A model made by calling the class (no registry name) is named by its class alone.
    avq.TabularSarsa(gym.make("avq/GridMaze-v0"), seed=0).learn(total_episodes=2).save(tmp_path / "direct.zip")
    direct = cli_in_process("evaluate", str(tmp_path / "direct.zip"), "--episodes", "1").stdout
    assert direct.startswith("TabularSarsa on avq/GridMaze-v0: return")


def test_resume_rewrites_an_emptied_progress_file_from_the_checkpoint(stopped_run, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(stopped_run, run)
    (run / "progress.csv").write_bytes(b"")
    result = cli_in_process("train", "--resume", str(run), "--no-progress")
    assert result.returncode == 0, result.stderr
    rows = list(csv.DictReader((run / "progress.csv").open(encoding="utf-8")))
    assert [int(r["episode"]) for r in rows] == list(range(1, 31))


def test_resume_with_a_foreign_progress_file_says_what_to_do_and_keeps_it(stopped_run, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(stopped_run, run)
    (run / "progress.csv").write_text("my,own,notes\n1,2,3\n", encoding="utf-8")
    line = one_error_line(cli_in_process("train", "--resume", str(run), "--no-progress"))
    assert f"{run / 'progress.csv'}: not a progress file written by avq" in line
    assert "move it away (or delete it) and run again" in line
    assert (run / "progress.csv").read_text(encoding="utf-8") == "my,own,notes\n1,2,3\n"


def test_save_into_a_missing_directory_is_refused_and_creates_nothing(tmp_path):
    agent = avq.TabularSarsa(gym.make("avq/GridMaze-v0"), seed=0).learn(total_episodes=1)
    with pytest.raises(FileNotFoundError) as caught:
        agent.save(tmp_path / "no" / "such" / "x.zip")
    assert f"the directory {tmp_path / 'no' / 'such'} does not exist; create it first" in str(caught.value)
    assert not (tmp_path / "no").exists()
    (tmp_path / "file").write_text("")
    with pytest.raises(OSError, match=f"{tmp_path / 'file'} is a file, not a directory"):
        agent.save(tmp_path / "file" / "sub" / "x.zip")


def test_train_refuses_a_directory_of_other_files_as_reproduce_does(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me", encoding="utf-8")
    line = one_error_line(cli_in_process("train", "--env", "avq/GridMaze-v0", "--episodes", "2", "--out", str(out)))
    assert line == (
        f"avq: error: --out {out} holds files that avq train did not write (notes.txt); give a new or empty directory"
    )
    assert [p.name for p in out.iterdir()] == ["notes.txt"]  # (not even a lock file)
    assert (out / "notes.txt").read_text(encoding="utf-8") == "keep me"
    for command in ("avq reproduce", "avq sweep"):  # the same rule, the same words
        with pytest.raises(ValueError, match=f"holds files that {command} did not write \\(notes.txt\\)"):
            check_output_dir(out, command)
    line = one_error_line(cli_in_process("reproduce", "--seeds", "1", "--trials", "1", "--out", str(out)))
    assert f"--out {out} holds files that avq reproduce did not write (notes.txt)" in line


def test_the_reproduction_table_prints_seconds_to_three_figures():
    summary = {
        "layout": "lau2002",
        "n_states": 98,
        "trials": 10,
        "seeds": [0, 1],
        "agents": {
            "fast": {
                "n_cells": [30, 32],
                "success_rate": [1.0, 1.0],
                "path_ratio": [1.1, 1.2],
                "env_steps": [1000, 1200],
                "wall_s": [0.0041, 0.0043],
            },
            "slow": {
                "n_cells": [98, 98],
                "success_rate": [1.0, 1.0],
                "path_ratio": [1.0, 1.0],
                "env_steps": [5000, 5000],
                "wall_s": [120.4, 130.6],
            },
        },
    }
    rows = {line.split()[0]: line.split()[-1] for line in format_table(summary).splitlines()[3:5]}
    assert rows == {"fast": "0.0042", "slow": "126"}


def test_tiles_reports_tiles(tmp_path):
    assert avq.TileSarsa.size_unit == "tiles"
    result = cli_in_process(
        "train", "--env", "MountainCar-v0", "--agent", "tiles", "--episodes", "1", "--out", str(tmp_path / "run")
    )
    assert result.returncode == 0, result.stderr
    assert " tiles, mean return" in result.stdout and " cells" not in result.stdout


def write_results(out, values: dict[str, list[float]]) -> None:
    """A sweep's results.csv by hand: configuration label (alpha) -> final_return per seed."""
    from avq.sweep.config import METRICS

    out.mkdir()
    columns = ["trial", "config", "agent", "seed_index", "seed", "config/alpha", "status", *METRICS, "error"]
    with open(out / "results.csv", "w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        for c, (alpha, returns) in enumerate(values.items()):
            for s, ret in enumerate(returns):
                writer.writerow(
                    {
                        "trial": f"c{c}-s{s}",
                        "config": c,
                        "agent": "avq",
                        "seed_index": s,
                        "seed": s,
                        "config/alpha": alpha,
                        "status": "ok",
                        "final_return": ret,
                        "error": "",
                    }
                )


def test_sweep_report_marks_an_interval_of_few_seeds_as_wide(tmp_path):
    write_results(tmp_path / "few", {"0.1": [-100.0, -120.0], "0.2": [-90.0, -95.0, -92.0, -94.0, -91.0]})
    lines = report(tmp_path / "few", metric="final_return").splitlines()
    two_seeds = next(line for line in lines if "alpha=0.1" in line).split()
    # mean -110, t-interval half-width 12.706 * 10 = 127 (wider than the range -120..-100): marked
    assert two_seeds[3:8] == ["-110", "127*", "-120", "-100", "2"]
    five_seeds = next(line for line in lines if "alpha=0.2" in line).split()
    assert not five_seeds[4].endswith("*")
    assert lines[-1].startswith("* from fewer than 5 seeds the 95% interval of the mean is wide")
    write_results(tmp_path / "many", {"0.2": [-90.0, -95.0, -92.0, -94.0, -91.0]})
    assert "fewer than" not in report(tmp_path / "many", metric="final_return")


def test_a_bad_parameter_is_a_public_value_error():
    with pytest.raises(avq.InvalidParameterError) as caught:
        avq.AVQSarsa(gym.make("avq/GridMaze-v0"), alpha=2)
    assert isinstance(caught.value, ValueError)
    shown = traceback.format_exception_only(type(caught.value), caught.value)
    assert shown == ["avq.InvalidParameterError: alpha must be in (0.0, 1.0], not 2\n"]
    assert (caught.value.name, caught.value.value) == ("alpha", 2)


@pytest.mark.parametrize(
    ("raised", "told"),
    [
        (
            "DependencyNotInstalled('pygame is not installed, run `pip install pygame`')",
            "DependencyNotInstalled: pygame is not installed, run `pip install pygame`",
        ),
        ("DependencyNotInstalled()", "DependencyNotInstalled: (no message)"),
    ],
    ids=["with-a-message", "without"],
)
def test_an_error_gymnasium_raises_for_its_users_is_one_line_with_exit_2(tmp_path, raised, told):
    # (as CartPole with render_mode "human" raises at its first reset without pygame: Gymnasium's message says
    # what to install)
    (tmp_path / "needs_extra.py").write_text(
        "import gymnasium as gym\n"
        "from gymnasium.envs.classic_control import CartPoleEnv\n\n\n"
        "class NeedsExtra(CartPoleEnv):\n"
        "    def reset(self, *, seed=None, options=None):\n"
        f"        raise gym.error.{raised}\n\n\n"
        "gym.register('user/NeedsExtra-v0', entry_point=NeedsExtra, max_episode_steps=50)\n",
        encoding="utf-8",
    )
    try:
        result = cli_in_process("train", "--env", "needs_extra:user/NeedsExtra-v0", "--episodes", "2", cwd=tmp_path)
    finally:
        gym.registry.pop("user/NeedsExtra-v0", None)
        sys.modules.pop("needs_extra", None)
    assert one_error_line(result) == f"avq: error: the environment raised {told}"


def test_a_directory_given_for_a_model_file_names_the_model_file_in_it(tmp_path):
    agent = avq.make_agent("tabular", gym.make("avq/GridMaze-v0"), seed=0).learn(total_episodes=2)
    trial = tmp_path / "trial"  # (as a sweep's trial directory: a model.zip without avq train's config.yml)
    trial.mkdir()
    agent.save(trial / "model.zip")
    with pytest.raises(ValueError) as caught:
        avq.load(trial)
    assert (
        str(caught.value)
        == f"{trial} is a directory, not a model file; give the model file in it: {trial / 'model.zip'}"
    )
    with pytest.raises(ValueError, match="is a directory, not a model file; give a model file written by agent.save"):
        avq.load(tmp_path)
    line = one_error_line(cli_in_process("evaluate", str(trial)))
    assert line == (
        f"avq: error: {trial}: no config.yml here (not a directory of 'avq train'); give the model file in it, "
        f"{trial / 'model.zip'}"
    )
    resume = one_error_line(cli_in_process("train", "--resume", str(trial)))  # (no model file to resume from)
    assert resume == f"avq: error: {trial}: no config.yml here; is this a directory written by 'avq train'?"


def test_resuming_a_finished_run_reports_the_directory_as_given(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    train("avq/GridMaze-v0", "tabular", episodes=3, out="runs/g", progress=False)
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    from avq.runs import resume_train

    summary = resume_train("../runs/g", progress=False)
    assert summary["already_finished"] and summary["out"] == "../runs/g"


def test_env_given_for_the_same_id_keeps_the_make_arguments_the_run_and_the_file_record(tmp_path):
    from avq.runs import evaluate_run

    run = tmp_path / "run"
    train("MountainCar-v0", "tiles", episodes=2, env_kwargs={"max_episode_steps": 20}, out=run, progress=False)
    for target in (run, run / "model.zip"):
        for env in (None, "MountainCar-v0"):
            assert evaluate_run(target, episodes=2, env=env)["mean_steps"] == 20.0, (target, env)
