"""Killed writers (SIGKILL) leave complete files, and a killed run resumes to the same result."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import avq
from avq.agents.callbacks import PROGRESS_COLUMNS
from avq.runs import train

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX signals")

_WRITER = textwrap.dedent("""
    import sys, gymnasium as gym, avq
    from avq._io import atomic_write_bytes
    from avq.plotting import plot_learning_curves
    import numpy as np
    out = sys.argv[1]
    agent = avq.make_agent("avq-paper", gym.make("avq/GridMaze-v0"), seed=0)
    k = 0
    while True:
        k += 1
        agent.learn(total_episodes=5)
        agent.save(out + "/model.zip")
        payload = (str(k) + "\\n") * (20000 + k)   # a file that is never the same size twice
        atomic_write_bytes(out + "/big.txt", payload.encode())
        plot_learning_curves({"a": [np.arange(k + 2.0)]}, out + "/curve.png")
        print(k, flush=True)
""")


def _wait_for(path: Path, timeout: float = 60.0) -> None:
    t = time.monotonic()
    while not path.exists():
        if time.monotonic() - t > timeout:
            raise TimeoutError(f"{path} never appeared")
        time.sleep(0.02)


def test_sigkill_during_writes_leaves_old_or_new_complete_files(tmp_path):
    rng = np.random.default_rng(0)
    for _ in range(4):
        proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(tmp_path)], stdout=subprocess.PIPE, text=True)
        try:
            _wait_for(tmp_path / "curve.png")
            time.sleep(float(rng.uniform(0.05, 0.6)))
        finally:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
        agent = avq.load(tmp_path / "model.zip")  # complete: it loads
        assert agent.num_episodes % 5 == 0 and agent.num_episodes > 0
        text = (tmp_path / "big.txt").read_text()
        k = int(text.split("\n", 1)[0])
        assert text == f"{k}\n" * (20000 + k)  # the whole of one version
        png = (tmp_path / "curve.png").read_bytes()
        assert png.startswith(b"\x89PNG") and png.endswith(b"IEND\xaeB`\x82")
        # Leftover temporary files never replace a real one.
        assert {p.name for p in tmp_path.iterdir() if not p.name.startswith(".")} == {
            "model.zip",
            "big.txt",
            "curve.png",
        }


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with zipfile.ZipFile(path) as zf, np.load(zf.open("arrays.npz")) as npz:
        return {k: npz[k] for k in npz.files if k != "history"}


# Slow (three processes, two killed); the fast run keeps the SIGKILL test above, test_resume.py's resume in a new
# process and test_output_dirs.py's resume of a stopped run.
@pytest.mark.slow
def test_a_run_killed_twice_and_resumed_equals_an_uninterrupted_run(tmp_path):
    kwargs = dict(episodes=2500, seed=4, params={"fused": False}, checkpoint_every=50, progress=False)
    reference = train("avq/GridMaze-v0", "avq-paper", out=tmp_path / "straight", **kwargs)
    run = tmp_path / "killed"
    cmd = [
        sys.executable,
        "-m",
        "avq.cli",
        "train",
        "--env",
        "avq/GridMaze-v0",
        "--agent",
        "avq-paper",
        "--episodes",
        "2500",
        "--seed",
        "4",
        "--set",
        "fused=false",
        "--checkpoint-every",
        "50",
        "--no-progress",
        "--out",
        str(run),
    ]
    for attempt in range(2):
        proc = subprocess.Popen(
            cmd if attempt == 0 else [sys.executable, "-m", "avq.cli", "train", "--resume", str(run), "--no-progress"]
        )
        try:
            _wait_for(run / "checkpoint.zip")
            if attempt:
                time.sleep(0.5)
        finally:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
        assert not (run / "model.zip").exists(), "the run finished before it was killed; make it longer"
        stopped_at = avq.load(run / "checkpoint.zip").num_episodes
        assert stopped_at % 50 == 0 and 0 < stopped_at < 2500
        lines = (run / "progress.csv").read_text().split("\n")
        assert lines[-1] == ""  # every row is a complete line
        assert all(len(row.split(",")) == len(PROGRESS_COLUMNS) for row in lines[1:-1])
    done = subprocess.run(
        [sys.executable, "-m", "avq.cli", "train", "--resume", str(run), "--no-progress"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    a, b = _arrays(tmp_path / "straight" / "model.zip"), _arrays(run / "model.zip")
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    summary = json.loads((run / "summary.json").read_text())
    assert summary["episodes"] == 2500 and summary["env_steps"] == reference["env_steps"]
    rows = (run / "progress.csv").read_text().splitlines()[1:]
    straight_rows = (tmp_path / "straight" / "progress.csv").read_text().splitlines()[1:]
    strip = lambda rs: [r.rsplit(",", 1)[0] for r in rs]  # noqa: E731  (all but wall_s)
    assert strip(rows) == strip(straight_rows) and len(rows) == 2500
    again = subprocess.run(
        [sys.executable, "-m", "avq.cli", "train", "--resume", str(run), "--no-progress"],
        capture_output=True,
        text=True,
    )
    assert again.returncode == 0 and "already finished" in again.stdout
