"""The budget of cells: the general ``avq`` keeps its partition bounded on any task, growth past the budget is
refused and counted, and ``progress.csv`` shows the cells and the refusals of every episode."""

import csv

import gymnasium as gym
import numpy as np

import avq
from avq._io import ProgressLog
from avq.agents.callbacks import PROGRESS_COLUMNS
from avq.cli import main

from conftest import ScriptedEnv

NO = False


def test_the_general_avq_has_a_budget_within_half_of_tiles_features():
    tiles = avq.make_agent("tiles", gym.make("MountainCar-v0"))
    for task in ("MountainCar-v0", "CartPole-v1", "Acrobot-v1"):  # (the general entry and the tasks' own)
        agent = avq.make_agent("avq", gym.make(task))
        assert 2 * agent.max_cells <= tiles.iht_size, task


def test_on_a_task_that_asks_for_more_the_default_budget_holds_and_counts_what_it_refuses():
    # 4-D observations on a lattice 1.5 apart (scale "auto": 20 per dimension, so 0.075 > d_min 0.05 apart), each
    # step a new point with a reward far from what the cell expects, and a decision every step (max_repeat 1): the
    # value trigger asks for a cell at every step.
    points = np.stack(np.meshgrid(*[np.arange(-6.0, 7.0, 1.5)] * 4, indexing="ij"), -1).reshape(-1, 4)
    steps = [(tuple(p), 100.0 * (-1) ** k, k == len(points) - 2, NO, NO) for k, p in enumerate(points[1:])]
    agent = avq.make_agent("avq-sarsa", ScriptedEnv([(tuple(points[0]), steps)], dims=4), seed=0, max_repeat=1)
    budget = agent.max_cells
    assert len(points) > budget + 100
    agent.learn(total_episodes=1)
    record = agent.history_[0]
    assert agent.n_cells == budget and record["n_cells"] == budget
    assert record["appends"] == budget - 1 and record["refused"] > 100


def test_progress_csv_shows_the_cells_and_the_refused_growth_of_every_episode(tmp_path):
    out = tmp_path / "run"
    assert (
        main(
            [
                "train",
                "--env",
                "CartPole-v1",
                "--agent",
                "avq",
                "--episodes",
                "20",
                "--seed",
                "0",
                "--no-progress",
                "--out",
                str(out),
                "--set",
                "max_cells=3",
            ]
        )
        == 0
    )
    with open(out / "progress.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    h = avq.load(out / "model.zip").episode_history()
    assert list(rows[0]) == list(PROGRESS_COLUMNS)
    for key in ("n_cells", "refused", "appends", "decisions"):
        assert [int(r[key]) for r in rows] == h[key].tolist(), key
    assert max(int(r["n_cells"]) for r in rows) == 3 and sum(int(r["refused"]) for r in rows) > 0


def test_a_progress_file_of_before_the_new_columns_is_written_again_with_them(tmp_path):
    path = tmp_path / "progress.csv"
    path.write_text("episode,steps,return\n1,10,-1.5\n2,11,-1.5\n")  # an older avq's columns
    history = [{"episode": k + 1, "steps": 10 + k, "return": -1.5, "refused": k} for k in range(3)]
    ProgressLog(path, ("episode", "steps", "return", "refused")).sync(history)
    assert path.read_text() == "episode,steps,return,refused\n1,10,-1.5,0\n2,11,-1.5,1\n3,12,-1.5,2\n"
