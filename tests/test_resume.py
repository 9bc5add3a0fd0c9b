"""Exact resume: learning N + M episodes straight equals N, a checkpoint, a new process, and M more."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq._io import ProgressLog
from avq.agents.callbacks import CheckpointCallback

CASES = [  # (agent, env id, episodes before the stop, episodes after, extra parameters)
    ("avq-paper", "avq/GridMaze-v0", 500, 500, {}),  # fused loop
    ("avq", "avq/GridMaze-v0", 60, 40, {"fused": False}),  # generic loop on the same maze
    ("tabular", "avq/GridMaze-v0", 500, 500, {}),
    ("avq", "MountainCar-v0", 4, 3, {}),
    ("grid", "MountainCar-v0", 4, 3, {}),
    ("tiles", "MountainCar-v0", 4, 3, {}),
]


def _saved(path):
    """Everything a saved agent holds except wall-clock times."""
    import json
    import zipfile

    with zipfile.ZipFile(path) as zf:
        meta = json.loads(zf.read("meta.json"))
        with np.load(zf.open("arrays.npz")) as npz:
            arrays = {k: npz[k] for k in npz.files}
    meta["state"].pop("wall_s")
    arrays["history"] = np.delete(arrays["history"], -1, axis=1)  # the wall_s column
    return meta, arrays


@pytest.mark.parametrize(("name", "env_id", "first", "then", "extra"), CASES)
def test_resume_in_a_new_process_is_bit_for_bit(tmp_path, name, env_id, first, then, extra):
    straight = avq.make_agent(name, gym.make(env_id), seed=3, **extra)
    straight.learn(total_episodes=first + then)
    straight.save(tmp_path / "straight.zip")

    stopped = avq.make_agent(name, gym.make(env_id), seed=3, **extra)
    stopped.learn(total_episodes=first, callback=CheckpointCallback(first, tmp_path / "ckpt"))
    script = textwrap.dedent(f"""
        import gymnasium as gym, avq
        agent = avq.load({str(tmp_path / "ckpt" / "checkpoint.zip")!r}, env=gym.make({env_id!r}))
        agent.learn(total_episodes={then})
        agent.save({str(tmp_path / "resumed.zip")!r})
    """)
    subprocess.run([sys.executable, "-c", script], check=True)

    meta_a, arrays_a = _saved(tmp_path / "straight.zip")
    meta_b, arrays_b = _saved(tmp_path / "resumed.zip")
    assert meta_a == meta_b  # parameters, counters and every generator's state
    assert arrays_a.keys() == arrays_b.keys()
    for key in arrays_a:
        assert np.array_equal(arrays_a[key], arrays_b[key]), key


def test_checkpoints_land_every_n_episodes_with_the_progress_rows(tmp_path):
    agent = avq.make_agent("avq-paper", gym.make("avq/GridMaze-v0"), seed=0)
    seen = []
    agent.learn(
        total_episodes=25,
        callback=[
            lambda a, r: seen.append((r["episode"], (tmp_path / "checkpoint.zip").exists())),
            CheckpointCallback(10, tmp_path),
        ],
    )
    assert avq.load(tmp_path / "checkpoint.zip").num_episodes == 20
    rows = (tmp_path / "progress.csv").read_text().splitlines()
    assert rows[0] == "episode,steps,return,n_cells,appends,merges,refused,decisions,wall_s"
    # Rows up to the last checkpoint, and at the end of learn the episodes after it too.
    assert [int(r.split(",")[0]) for r in rows[1:]] == list(range(1, 26))
    assert [int(r.split(",")[1]) for r in rows[1:]] == [h["steps"] for h in agent.history_]
    assert seen[9] == (10, False) and seen[10] == (11, True)  # saved right after episode 10


def test_checkpoint_arguments_are_checked(tmp_path):
    agent = avq.make_agent("tabular", gym.make("avq/GridMaze-v0"), seed=0)
    with pytest.raises(ValueError, match="checkpoint every"):
        CheckpointCallback(0, tmp_path)
    (tmp_path / "f").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        CheckpointCallback(1, tmp_path / "f")
    with pytest.raises(TypeError, match="callback must be a BaseCallback or callable"):
        agent.learn(total_episodes=1, callback=[CheckpointCallback(1, tmp_path), "oops"])


def test_a_checkpoint_in_the_fused_loop_lands_where_the_python_path_puts_it(tmp_path):
    # The compiled loop stops at each multiple of `every` for the callback: the checkpoints of both paths hold the
    # same agent, episode for episode (fused=False steps the maze from Python).
    for fused in (True, False):
        agent = avq.make_agent("avq-paper", gym.make("avq/GridMaze-v0"), seed=5, fused=fused)
        agent.learn(total_episodes=17, callback=CheckpointCallback(8, tmp_path / str(fused)))
    a, b = (avq.load(tmp_path / str(f) / "checkpoint.zip") for f in (True, False))
    assert a.num_episodes == b.num_episodes == 16 and np.array_equal(a.q_, b.q_) and a.num_timesteps == b.num_timesteps


def _history(n):
    return [{"episode": k + 1, "steps": 10 + k, "return": -1.5} for k in range(n)]


def test_progress_log_repairs_a_torn_line_and_drops_rows_past_the_checkpoint(tmp_path):
    path = tmp_path / "progress.csv"
    log = ProgressLog(path, ("episode", "steps", "return"))
    log.sync(_history(3))
    assert path.read_text() == "episode,steps,return\n1,10,-1.5\n2,11,-1.5\n3,12,-1.5\n"
    with open(path, "a") as f:
        f.write("4,13,-1.5\n5,1")  # a row written after the checkpoint, and one cut by a crash
    ProgressLog(path, ("episode", "steps", "return")).sync(_history(3))
    assert path.read_text() == "episode,steps,return\n1,10,-1.5\n2,11,-1.5\n3,12,-1.5\n"
    log = ProgressLog(path, ("episode", "steps", "return"))
    log.sync(_history(5))
    assert path.read_text().splitlines()[-1] == "5,14,-1.5"
    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="not a progress file"):
        ProgressLog(tmp_path / "other.csv", ("episode",)).sync(_history(1))


def test_a_run_written_before_an_option_existed_resumes_with_the_option_off(tmp_path):
    # A run of `avq` on the grid maze from a version without merging and known_radius: its config.yml lacks
    # them, and so does its checkpoint (here: written with them off). Resuming must take the class's defaults
    # for them (off), not the maze defaults of `avq` (rho 25, known_radius 0.3).
    import yaml

    from avq.runs import resume_train, train

    out = tmp_path / "run"
    train(
        "avq/GridMaze-v0",
        agent="avq",
        episodes=30,
        seed=1,
        out=out,
        checkpoint_every=10,
        progress=False,
        params={"rho": None, "known_radius": None},
    )
    config = yaml.safe_load((out / "config.yml").read_text())
    for key in ("rho", "known_radius", "merge_neighbours", "merge_same_action"):
        del config["params"][key]
    (out / "config.yml").write_text(yaml.safe_dump(config))
    finished = avq.load(out / "model.zip")
    (out / "model.zip").unlink()
    (out / "summary.json").unlink()
    resume_train(out, progress=False)
    resumed = avq.load(out / "model.zip")
    assert resumed.rho is None and resumed.known_radius is None and resumed.num_episodes == 30
    assert np.array_equal(resumed.q_, finished.q_)
