"""What `avq reproduce`, `avq evaluate` and `avq train` show and leave behind: the output directory, the step
cap of evaluations, model files, timings, progress bars and help texts."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest
import yaml

import avq
from avq.agents.registry import AGENTS
from avq.cli import main
from avq.reproduce import reproduce
from avq.runs import evaluate_run, resume_train

SMALL = ["--seeds", "2", "--trials", "10", "--jobs", "1", "--no-progress"]


def files(directory: Path) -> dict[str, bytes]:
    """Every file under ``directory`` (relative path -> content)."""
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory):
    """A small reproduction with two AVQ agents and tabular (every kind of file it writes)."""
    out = tmp_path_factory.mktemp("rep") / "out"
    assert main(["reproduce", "--agents", "avq-paper,avq,tabular", *SMALL, "--out", str(out)]) == 0
    return out


# -- 5: the output directory of avq reproduce ------------------------------------------------------------------


def test_a_partial_reproduction_replaces_the_earlier_one_whole(reproduced, tmp_path, capsys):
    out = tmp_path / "out"
    shutil.copytree(reproduced, out)
    assert "partition-avq.png" in files(out) and "models/avq__seed1.zip" in files(out)
    args = ["reproduce", "--agents", "tabular", "--seeds", "1", "--trials", "10", "--jobs", "1", "--no-progress"]
    assert main(args + ["--out", str(out)]) == 0
    assert main(args + ["--out", str(tmp_path / "fresh")]) == 0
    assert (
        set(files(out))
        == set(files(tmp_path / "fresh"))
        == {"summary.json", "partition.png", "learning_curve.png", "models/tabular__seed0.zip"}
    )
    assert list(json.loads((out / "summary.json").read_text())["agents"]) == ["tabular"]
    left = sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock"))  # (the locks stay)
    assert left == ["fresh", "out"]  # no staging directory left
    assert f"wrote {out}: learning_curve.png, partition.png, summary.json, models/ (1 file)" in capsys.readouterr().out


def test_a_reproduction_that_stops_leaves_the_directory_as_it_was(reproduced, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(reproduced, out)
    before = files(out)

    def stop(line):  # Ctrl-C once everything is trained and drawn (the log prints the table last)
        if "success mean" in line:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        reproduce(
            seeds=[0, 1, 2], trials=12, agents=["avq-paper", "tabular"], out=out, n_jobs=1, progress=False, log=stop
        )
    assert files(out) == before
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == ["out"]


def test_reproduce_refuses_a_directory_with_other_files(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(["reproduce", *SMALL, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out {out} holds files that avq reproduce did not write (notes.txt)" in err
    assert "give a new or empty directory" in err
    assert files(out) == {"notes.txt": b"keep me"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]


# -- 6: episodes cut by the step cap of avq evaluate -----------------------------------------------------------


@pytest.fixture(scope="module")
def cliff_run(tmp_path_factory):
    """A tabular run on CliffWalking-v1 (no time limit) trained for 3 episodes: its greedy policy loops forever."""
    out = tmp_path_factory.mktemp("cliff") / "run"
    assert (
        main(
            [
                "train",
                "--env",
                "CliffWalking-v1",
                "--agent",
                "tabular",
                "--episodes",
                "3",
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    return out


def test_evaluate_reports_the_episodes_cut_by_the_step_cap(cliff_run, capsys):
    capsys.readouterr()
    assert main(["evaluate", str(cliff_run), "--episodes", "3", "--max-steps", "300", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["capped"] == 3 and report["max_steps"] == 300
    assert report["mean_steps"] == 300.0 and report["mean_return"] == -300.0
    assert main(["evaluate", str(cliff_run), "--episodes", "3", "--max-steps", "300"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith(
        "tabular (TabularSarsa) on CliffWalking-v1: return -300.00 ± 0.00 over 3 episodes, 300.0 steps"
    )
    assert lines[1] == (
        "3 of 3 episodes did not end within --max-steps 300 and were cut there "
        "(their return is that of the first 300 steps)"
    )


def test_an_episode_that_the_environment_ends_is_not_counted_as_capped(tmp_path, capsys):
    out = tmp_path / "maze"
    assert (
        main(
            [
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
        )
        == 0
    )
    capsys.readouterr()
    # The maze's own limit is 100 steps: an episode it truncates at 100 was not cut by --max-steps 100.
    assert main(["evaluate", str(out), "--max-steps", "100", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["capped"] == 0 and report["mean_steps"] == 100.0
    assert main(["evaluate", str(out), "--max-steps", "100"]) == 0
    assert "cut" not in capsys.readouterr().out
    proc = subprocess.run(
        [sys.executable, "-m", "avq.cli", "evaluate", str(out), "--max-steps", "0"], capture_output=True, text=True
    )
    assert proc.returncode == 2 and "--max-steps must be >= 1" in proc.stderr
    assert (
        "--max-steps N"
        in subprocess.run(
            [sys.executable, "-m", "avq.cli", "evaluate", "--help"], capture_output=True, text=True
        ).stdout
    )


# Slow (100,000 steps); the fast run keeps the capped evaluation above and the progress bars of learn and train.
@pytest.mark.slow
def test_a_long_evaluation_shows_progress_but_not_into_a_file(cliff_run, capsys):
    capsys.readouterr()
    report = evaluate_run(cliff_run, episodes=1, progress=True)  # 100,000 steps: a few seconds
    err = capsys.readouterr().err
    assert report["capped"] == 1
    final = err.split("\r")[-1]
    assert final.startswith("evaluate: 100%") and "1/1" in final and "100000 steps" in final
    # The command line draws bars only on a terminal (here stderr is captured), as for --no-progress.
    assert main(["evaluate", str(cliff_run), "--episodes", "1", "--json"]) == 0
    assert capsys.readouterr().err == ""


def test_evaluate_says_what_success_is_where_it_is_lasting_until_the_time_limit(tmp_path, capsys):
    out = tmp_path / "cp"
    args = ["train", "--env", "CartPole-v1", "--agent", "tabular", "--episodes", "2", "--out", str(out)]
    assert main([*args, "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(out), "--episodes", "2", "--json"]) == 0
    rate = json.loads(capsys.readouterr().out)["success_rate"]
    assert main(["evaluate", str(out), "--episodes", "2"]) == 0
    line = capsys.readouterr().out.splitlines()[0]
    assert line.endswith(f", success {rate:.0%} (episodes that lasted until the time limit or --max-steps)")


# -- 7: avq evaluate on a model file ---------------------------------------------------------------------------


def test_evaluate_takes_a_model_file(reproduced, capsys):
    summary = json.loads((reproduced / "summary.json").read_text())
    capsys.readouterr()
    model = reproduced / "models" / "avq-paper__seed1.zip"
    assert main(["evaluate", str(model), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert (
        report["run"] == str(model)
        and report["env"] == "avq/GridMaze-v0"
        and (report["agent"], report["class"]) == ("avq-paper", "AVQSarsa")
    )
    assert report["n_cells"] == summary["agents"]["avq-paper"]["n_cells"][1]
    assert report["maze_success_rate"] == summary["agents"]["avq-paper"]["success_rate"][1]
    # The same numbers as for a run directory holding that model.
    run = reproduced.parent / "as-run"
    run.mkdir()
    shutil.copy(model, run / "model.zip")
    (run / "config.yml").write_text(
        yaml.safe_dump(
            {
                "env": "avq/GridMaze-v0",
                "agent": "avq-paper",
                "env_kwargs": {"layout": avq.load(model).env.spec.kwargs["layout"], "start": "random"},
            }
        )
    )
    assert main(["evaluate", str(run), "--json"]) == 0
    as_run = json.loads(capsys.readouterr().out)
    assert {k: v for k, v in as_run.items() if k not in ("run", "agent")} == {
        k: v for k, v in report.items() if k not in ("run", "agent")
    }


# -- 13 and 14: timings without the compilation, progress bars -------------------------------------------------


@pytest.fixture(scope="module")
def fresh_process_reproduction(tmp_path_factory):
    """A reproduction in a new process (whose kernels are not loaded yet), with its progress bar."""
    out = tmp_path_factory.mktemp("fresh") / "out"
    code = (
        "import json, sys; from avq.reproduce import reproduce; "
        f"s = reproduce(seeds=[0, 1, 2], trials=20, agents=['avq-paper', 'tabular'], out={str(out)!r}, "
        "n_jobs=1, progress=True, log=None); print(json.dumps(s))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout), proc.stderr


def test_the_seconds_of_the_first_run_hold_no_compilation(fresh_process_reproduction):
    summary, _ = fresh_process_reproduction
    for name, res in summary["agents"].items():
        first, later = res["wall_s"][0], max(res["wall_s"][1:])
        assert first <= 0.1 + 5 * later, (name, res["wall_s"])  # loading the kernels alone takes ~0.5 s
    assert summary["warmup_s"] > max(max(res["wall_s"]) for res in summary["agents"].values())


def test_the_reproduce_bar_starts_after_the_compilation(fresh_process_reproduction):
    summary, err = fresh_process_reproduction
    final = [s for s in re.split(r"[\r\n]", err) if s.strip()][-1]  # (into a pipe, tqdm ends lines with \n)
    assert final.startswith("reproduce: 100%") and "6/6" in final
    rate = re.search(r"([\d.]+)(run/s|s/run)", final)
    elapsed = 6 / float(rate[1]) if rate[2] == "run/s" else 6 * float(rate[1])
    assert elapsed < summary["warmup_s"]


def test_the_quick_start_bar_stays_and_shows_the_end(capsys):
    agent = avq.make_agent("avq-paper", gym.make("avq/GridMaze-v0", layout="lau2002"), seed=0)
    agent.learn(total_episodes=1000, progress_bar=True)
    err = capsys.readouterr().err
    assert err.endswith("\n") and "1000/1000" in err.split("\r")[-1]


def test_a_resumed_run_counts_its_bar_from_the_episodes_done(tmp_path, capsys):
    run = tmp_path / "run"
    assert (
        main(
            [
                "train",
                "--env",
                "avq/GridMaze-v0",
                "--agent",
                "tabular",
                "--episodes",
                "20",
                "--checkpoint-every",
                "10",
                "--out",
                str(run),
                "--no-progress",
            ]
        )
        == 0
    )
    # As if stopped after the checkpoint at episode 20 of 30.
    config = yaml.safe_load((run / "config.yml").read_text())
    (run / "config.yml").write_text(yaml.safe_dump({**config, "episodes": 30}, sort_keys=False))
    (run / "model.zip").unlink()
    (run / "summary.json").unlink()
    capsys.readouterr()
    assert resume_train(run, progress=True)["episodes"] == 30
    bars = [s for s in capsys.readouterr().err.split("\r") if s.strip()]
    assert "20/30" in bars[0] and "30/30" in bars[-1]


# -- 16: help texts and messages -------------------------------------------------------------------------------


def help_text(command):
    env = {**os.environ, "COLUMNS": "1000"}  # one line per option: names are not wrapped at their hyphens
    proc = subprocess.run([sys.executable, "-m", "avq.cli", command, "--help"], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_reproduce_help_lists_every_file_it_writes(reproduced):
    text = help_text("reproduce")
    names = sorted(AGENTS, key=len, reverse=True)
    for path in files(reproduced):
        pattern = re.sub(r"seed\d+", "seedS", re.sub("|".join(map(re.escape, names)), "NAME", path))
        assert pattern in text, path
    assert "replace it as a whole" in text


def test_train_help_lists_every_agent():
    text = help_text("train")
    for name in AGENTS:
        assert re.search(rf"[ ,]{re.escape(name)}(,|\s)", text), name


def test_env_kwargs_with_a_hash_says_it_starts_a_comment_and_how_to_quote(tmp_path, capsys):
    args = ["train", "--env", "avq/GridMaze-v0", "--agent", "tabular", "--episodes", "2", "--no-progress"]
    assert main(args + ["--env-kwargs", "layout=[#####, #S.G#, #####]", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "in YAML '#' starts a comment" in err
    fix = re.search(r'--env-kwargs "(.*)"$', err.strip())[1]
    assert fix == "layout=['#####', '#S.G#', '#####']"
    assert main(args + ["--env-kwargs", fix, "--out", str(tmp_path / "b")]) == 0
    assert main(args + ["--env-kwargs", "layout=#S.G#", "--out", str(tmp_path / "c")]) == 2
    assert "in YAML '#' starts a comment" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "c").exists()


def test_an_empty_value_is_named_as_empty(tmp_path, capsys):
    for flag in ("--env-kwargs", "--set"):
        assert (
            main(
                [
                    "train",
                    "--env",
                    "avq/GridMaze-v0",
                    flag,
                    "layout=" if flag == "--env-kwargs" else "alpha=",
                    "--out",
                    str(tmp_path / "x"),
                    "--no-progress",
                ]
            )
            == 2
        )
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{flag} " in err and ": the value is empty" in err and "=null" in err
    assert not (tmp_path / "x").exists()
