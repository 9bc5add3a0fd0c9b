"""benchmarks/compare.py: steps to a return threshold, its table cell, and one tiny run of the script."""

import csv
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SPEC = importlib.util.spec_from_file_location("compare", ROOT / "benchmarks" / "compare.py")
compare = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(compare)


def test_steps_to_threshold_ends_at_the_first_window_whose_mean_reaches_it():
    # 20 episodes of -200 (200 steps each), then 5 of -100 (100 steps each); windows of 20 episodes.
    returns = np.array([-200.0] * 20 + [-100.0] * 5)
    steps = np.array([200] * 20 + [100] * 5)
    # The windows ending at episodes 20..24 have the means -200, -195, -190, -185, -180 (the -100s come in one
    # by one); -180 is first reached by the window ending at episode 24.
    assert compare.steps_to_threshold(returns, steps, -180.0) == 20 * 200 + 4 * 100
    assert compare.steps_to_threshold(returns, steps, -200.0) == 20 * 200
    assert compare.steps_to_threshold(returns, steps, -150.0) is None  # best window: -175
    assert compare.steps_to_threshold(returns[:19], steps[:19], -1000.0) is None  # no whole window


def test_threshold_cell_counts_runs_that_never_got_there_as_more_than_their_steps():
    rows = [
        {"steps_to_threshold": 1000, "env_steps": 5000},
        {"steps_to_threshold": None, "env_steps": 20_000},
        {"steps_to_threshold": 3000, "env_steps": 6000},
    ]
    # Median of 1000, 3000 and "more than 20,000": 3000; the range is that of the two runs that got there.
    assert compare.threshold_cell(rows) == "3.0k [1.0k–3.0k], 2/3"
    # Two of three never got there: the median is more than the median of the steps known (1000, 20k, 40k).
    rows[2] = {"steps_to_threshold": None, "env_steps": 40_000}
    assert compare.threshold_cell(rows) == "> 20k [1.0k–1.0k], 1/3"
    assert compare.threshold_cell(rows[1:]) == "> 30k, 0/2"


def test_a_tiny_run_writes_its_rows_table_and_figure(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "compare.py"),
            "--tasks",
            "CartPole-v1",
            "--agents",
            "avq,grid",
            "--seeds",
            "2",
            "--scale",
            "0.01",
            "--jobs",
            "1",
            "--out",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    with open(tmp_path / "data" / "compare.csv") as f:
        rows = list(csv.DictReader(f))
    # The agents asked for, and the random policy, 2 seeds each, 20 episodes (the least: a whole window).
    assert [(r["agent"], r["seed"]) for r in rows] == [(a, s) for a in ("avq", "grid", "random") for s in "01"]
    assert {r["episodes"] for r in rows} == {"20"} and {r["threshold"] for r in rows} == {"195.0"}
    assert all(r["cells"] == "" for r in rows if r["agent"] == "random")
    assert all(int(r["cells_100"]) == int(r["cells"]) > 0 for r in rows if r["agent"] != "random")
    table = (tmp_path / "data" / "compare_table.md").read_text()
    assert "| CartPole-v1 | random |" in table and "Cells over time" in table and "Mountain Car check" not in table
    assert "| CartPole-v1 | avq |" in table.split("seeds above random")[1]
    assert (tmp_path / "figures" / "compare_CartPole-v1.png").stat().st_size > 10_000


# Slow (three runs of the script in new processes); the fast run keeps test_a_tiny_run_writes_its_rows_table_and_figure.
@pytest.mark.slow
def test_update_reruns_some_agents_and_keeps_the_rows_of_the_others(tmp_path):
    def compare(*args):
        out = subprocess.run(
            [
                sys.executable,
                str(ROOT / "benchmarks" / "compare.py"),
                "--tasks",
                "CartPole-v1",
                "--seeds",
                "2",
                "--scale",
                "0.01",
                "--jobs",
                "1",
                "--out",
                str(tmp_path),
                *args,
            ],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert out.returncode == 0, out.stderr
        with open(tmp_path / "data" / "compare.csv") as f:
            return list(csv.DictReader(f))

    first = compare("--agents", "avq,grid")
    # grid again with another budget: its rows change, those of avq and random stay as they were.
    second = compare("--agents", "grid", "--scale", "0.02", "--update")
    assert [(r["agent"], r["seed"]) for r in second] == [(a, s) for a in ("avq", "random", "grid") for s in "01"]
    assert [r for r in second if r["agent"] != "grid"] == [r for r in first if r["agent"] != "grid"]
    grid = [r for r in second if r["agent"] == "grid"]
    assert all(float(r["env_steps"]) > 0 for r in grid) and grid != [r for r in first if r["agent"] == "grid"]
    curves = json.loads((tmp_path / "data" / "compare_curves.json").read_text())
    assert [(c["agent"], c["seed"]) for c in curves] == [(r["agent"], int(r["seed"])) for r in second]
    table = (tmp_path / "data" / "compare_table.md").read_text()
    assert all(f"| CartPole-v1 | {a} |" in table for a in ("avq", "grid", "random"))
    # A task new to the file: the random policy runs there too (its rows on the other task are kept).
    third = compare("--agents", "grid", "--tasks", "CartPole-v0", "--update")
    assert third[:6] == second
    assert [(r["task"], r["agent"], r["seed"]) for r in third[6:]] == [
        ("CartPole-v0", a, s) for a in ("grid", "random") for s in "01"
    ]
    table = (tmp_path / "data" / "compare_table.md").read_text()
    assert all(f"| CartPole-v0 | {a} |" in table for a in ("grid", "random"))
    assert (tmp_path / "figures" / "compare_CartPole-v0.png").stat().st_size > 10_000


def test_set_gives_every_agent_run_a_parameter_on_top_of_the_tasks_settings():
    # A budget of 3 cells on top of Acrobot's settings: the run keeps 3 cells, where it grows more without; the
    # task's settings are left as they were.
    settings = json.dumps(compare.TASKS["Acrobot-v1"])
    capped = compare.run_one("Acrobot-v1", "avq", 0, 2, {"max_cells": 3})
    assert capped["cells"] == 3 and compare.run_one("Acrobot-v1", "avq", 0, 2)["cells"] > 3
    assert json.dumps(compare.TASKS["Acrobot-v1"]) == settings


# Slow (the script in new processes); the fast run keeps --set's parameters on top of the task's settings above.
@pytest.mark.slow
def test_set_is_read_as_avq_train_reads_it_and_never_writes_over_the_results(tmp_path):
    def run(*args):
        return subprocess.run(
            [
                sys.executable,
                str(ROOT / "benchmarks" / "compare.py"),
                "--tasks",
                "CartPole-v1",
                "--agents",
                "avq",
                "--seeds",
                "1",
                "--scale",
                "0.01",
                "--jobs",
                "1",
                *args,
            ],
            capture_output=True,
            text=True,
            timeout=600,
        )

    bad = run("--set", "d_min", "--out", str(tmp_path))
    assert bad.returncode == 2 and "--set expects key=value, not 'd_min'" in bad.stderr
    docs = run("--set", "d_min=0.1")  # (--out docs, the default)
    assert docs.returncode == 2 and "--set gives trial settings; write them elsewhere" in docs.stderr
    assert not (tmp_path / "data").exists()
