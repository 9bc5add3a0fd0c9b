"""Output directories: one avq process at a time, failed writes that name the user's path, stopped
runs and sweeps that say how to go on, and sweep workers that end with their sweep."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import avq
from avq.agents.callbacks import PROGRESS_COLUMNS
from avq.cli import main

posix_only = pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX signals")

# A training run, a sweep and a reproduction long enough to be caught in the act.
LONG_TRAIN = [
    "train",
    "--env",
    "MountainCar-v0",
    "--agent",
    "avq-paper",
    "--episodes",
    "100000",
    "--checkpoint-every",
    "5",
    "--no-progress",
]
LONG_SWEEP = {"env": "MountainCar-v0", "agents": ["avq-paper"], "seeds": 6, "episodes": 400, "eval_episodes": 0}


def avq_cli(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "avq.cli", *map(str, args)], capture_output=True, text=True, cwd=cwd)


def _default_sigint() -> None:
    # A shell without job control starts a background command with SIGINT ignored, and an ignored signal stays
    # ignored in every process it starts: the avq started here must see Ctrl-C however pytest was started.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(*args, cwd=None) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "avq.cli", *map(str, args)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
        preexec_fn=_default_sigint if os.name == "posix" else None,
    )


def wait_until(check, proc: subprocess.Popen | None = None, timeout: float = 120.0) -> None:
    t = time.monotonic()
    while not check():
        assert proc is None or proc.poll() is None, f"the process ended early: {proc.stderr.read()}"
        assert time.monotonic() - t < timeout, "timed out"
        time.sleep(0.02)


def holder(lock: Path) -> str:
    return lock.read_text().strip() if lock.exists() else ""


def kill(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGKILL)
    proc.wait()


def one_line_error(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("avq: error: "), proc.stderr
    return lines[0]


# -- 8: a run killed before its first checkpoint ---------------------------------------------------


def test_train_refuses_a_run_stopped_before_its_first_checkpoint_and_resume_continues_it(tmp_path):
    run = tmp_path / "run"
    args = ["train", "--env", "avq/GridMaze-v0", "--agent", "tabular", "--episodes", "20", "--no-progress"]
    assert main([*args, "--seed", "0", "--out", str(run)]) == 0
    for name in ("checkpoint.zip", "progress.csv", "model.zip", "summary.json"):
        (run / name).unlink(missing_ok=True)  # as a run killed before its first checkpoint leaves it: config.yml only
    config = (run / "config.yml").read_bytes()
    line = one_line_error(avq_cli(*args, "--seed", "1", "--out", run))
    assert f"{run} holds a run stopped before its first checkpoint" in line
    assert f"avq train --resume {run}" in line and "choose another --out" in line
    assert f"to start again with other settings, remove {run} (it holds no checkpoint" in line
    assert (run / "config.yml").read_bytes() == config and sorted(
        p.name for p in run.iterdir() if p.name != ".avq.lock"
    ) == ["config.yml"]
    assert main(["train", "--resume", str(run), "--no-progress"]) == 0
    assert yaml.safe_load((run / "summary.json").read_text())["seed"] == 0


# -- 10: paths that cannot be written ---------------------------------------------------------------


@pytest.fixture
def unwritable(tmp_path):
    """A directory in which no file can be created (chmod 0o500; as root, which ignores that, /sys)."""
    d = tmp_path / "imm"
    d.mkdir()
    d.chmod(0o500)
    if os.access(d, os.W_OK):  # root: permission bits do not stop it
        d.chmod(0o700)
        d = Path("/sys")
    try:
        fd, name = tempfile.mkstemp(dir=d)
    except PermissionError:
        yield d
    else:
        os.close(fd)
        os.unlink(name)
        pytest.skip(f"no directory here refuses writes ({d} accepts them)")
    finally:
        (tmp_path / "imm").chmod(0o700)


def _command(kind: str, out: Path, cwd: Path) -> list[str]:
    (cwd / "s.yml").write_text(yaml.safe_dump({"env": "avq/GridMaze-v0", "agents": ["tabular"], "episodes": 2}))
    return {
        "train": ["train", "--env", "avq/GridMaze-v0", "--episodes", "2", "--no-progress", "--out", str(out)],
        "sweep": ["sweep", "s.yml", "--no-progress", "--out", str(out)],
        "reproduce": [
            "reproduce",
            "--seeds",
            "1",
            "--trials",
            "2",
            "--agents",
            "tabular",
            "--no-progress",
            "--out",
            str(out),
        ],
    }[kind]


@pytest.mark.parametrize("kind", ["train", "sweep", "reproduce"])
def test_an_out_under_a_file_names_the_file(kind, tmp_path):
    (tmp_path / "afile.txt").write_text("keep me")
    line = one_line_error(avq_cli(*_command(kind, Path("afile.txt/sub"), tmp_path), cwd=tmp_path))
    assert "cannot write afile.txt" in line and "afile.txt is a file, not a directory" in line
    assert "Errno" not in line and (tmp_path / "afile.txt").read_text() == "keep me"


@pytest.mark.parametrize(
    "kind,inside", [("train", "run"), ("sweep", "run"), ("reproduce", "run"), ("train", ""), ("sweep", "")]
)  # a new directory in it, or it
def test_an_out_that_cannot_be_written_names_it(kind, inside, unwritable, tmp_path):
    out = unwritable / inside
    line = one_line_error(avq_cli(*_command(kind, out, tmp_path), cwd=tmp_path))
    if kind == "train" and out == unwritable and any(out.iterdir()):  # (root: /sys, which holds files)
        # train refuses a folder of other files before it writes anything there (its lock file included)
        assert line.startswith(f"avq: error: --out {out} holds files that avq train did not write (")
        assert line.endswith("; give a new or empty directory")
        return
    assert f"cannot write {unwritable}" in line  # the directory given or the one it would be made in
    assert f"no permission to write in {unwritable}" in line and "choose a directory you can write to" in line
    assert "Errno" not in line and ".tmp" not in line


def test_save_to_an_unwritable_place_names_the_users_path(unwritable, tmp_path):
    agent = avq.make_agent("tabular", gym.make("avq/GridMaze-v0"), seed=0).learn(total_episodes=1)
    with pytest.raises(OSError) as caught:
        agent.save(unwritable / "m.zip")
    assert caught.value.errno in (errno.EACCES, errno.EPERM) and caught.value.filename == str(unwritable / "m.zip")
    assert str(caught.value) == (
        f"cannot write {unwritable / 'm.zip'}: no permission to write in {unwritable}; "
        "choose a directory you can write to, or change its permissions"
    )
    (tmp_path / "afile.txt").write_text("x")
    with pytest.raises(OSError, match=r"^cannot write .*afile.txt/m.zip: .*afile.txt is a file, not a directory"):
        agent.save(tmp_path / "afile.txt" / "m.zip")


# -- 19: a full disk during training ----------------------------------------------------------------


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with zipfile.ZipFile(path) as zf, np.load(zf.open("arrays.npz")) as npz:
        return {k: npz[k] for k in npz.files if k != "history"}


# The 7th flush to disk is progress.csv's at episode 30, the 8th the checkpoint's.
@pytest.mark.parametrize("fail_at", [7, 8])
def test_a_full_disk_names_the_file_the_checkpoint_and_the_resume_command(fail_at, tmp_path, monkeypatch, capsys):
    args = [
        "train",
        "--env",
        "avq/GridMaze-v0",
        "--agent",
        "avq-paper",
        "--episodes",
        "50",
        "--seed",
        "2",
        "--checkpoint-every",
        "10",
        "--no-progress",
        "--out",
    ]
    assert main([*args, str(tmp_path / "straight")]) == 0
    run = tmp_path / "run"
    calls = []
    real_fsync = os.fsync

    def fsync(fd):
        calls.append(fd)
        if len(calls) == fail_at:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    capsys.readouterr()
    assert main([*args, str(run)]) == 2
    monkeypatch.undo()
    line = capsys.readouterr().err.strip()
    stopped_at = avq.load(run / "checkpoint.zip").num_episodes  # the checkpoint is whole
    assert stopped_at == 20
    failed = "progress.csv" if fail_at == 7 else "checkpoint.zip"
    assert line == (
        f"avq: error: cannot write {run / failed}: no space left on the device (or over the disk quota) "
        f"of {run}; free some space; the run stopped at its checkpoint after episode 20. "
        f"Continue it with: avq train --resume {run}"
    )
    rows = (run / "progress.csv").read_text().split("\n")
    assert rows[-1] == "" and all(len(r.split(",")) == len(PROGRESS_COLUMNS) for r in rows[1:-1])  # complete lines only
    assert main(["train", "--resume", str(run), "--no-progress"]) == 0
    a, b = _arrays(tmp_path / "straight" / "model.zip"), _arrays(run / "model.zip")
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    strip = lambda path: [r.rsplit(",", 1)[0] for r in path.read_text().splitlines()]  # noqa: E731  (not wall_s)
    assert strip(run / "progress.csv") == strip(tmp_path / "straight" / "progress.csv")


# -- 18: one process per output directory -----------------------------------------------------------


@posix_only
def test_a_second_train_into_a_busy_directory_is_refused_until_the_first_is_killed(tmp_path):
    run, lock = tmp_path / "run", tmp_path / "run" / ".avq.lock"
    first = start(*LONG_TRAIN, "--seed", "0", "--out", run)
    try:
        wait_until(lambda: (run / "checkpoint.zip").exists(), first)
        config = (run / "config.yml").read_bytes()
        for second in ([*LONG_TRAIN, "--seed", "1", "--out", run], ["train", "--resume", run]):
            line = one_line_error(avq_cli(*second))
            assert line == (
                f"avq: error: {run} is in use by another avq process (pid {first.pid}); "
                "wait until it ends, or choose another --out"
            )
        assert (run / "config.yml").read_bytes() == config
    finally:
        kill(first)
    again = start("train", "--resume", run, "--no-progress")  # the kill left no stuck lock
    try:
        wait_until(lambda: holder(lock) == str(again.pid), again)
    finally:
        kill(again)
    assert yaml.safe_load((run / "config.yml").read_text())["seed"] == 0


@posix_only
# Slow (a sweep in a new process); the fast run keeps the same lock on a busy avq train directory above.
@pytest.mark.slow
def test_a_busy_sweep_directory_refuses_a_second_sweep_and_a_run(tmp_path):
    (tmp_path / "s.yml").write_text(yaml.safe_dump(LONG_SWEEP))
    out = tmp_path / "sweep"
    cmd = ["sweep", tmp_path / "s.yml", "--out", out, "--jobs", "1", "--no-progress"]
    first = start(*cmd)
    try:
        wait_until(lambda: (out / "sweep.json").exists(), first)
        busy = f"avq: error: {out} is in use by another avq process (pid {first.pid})"
        assert one_line_error(avq_cli(*cmd)).startswith(busy)
        assert one_line_error(avq_cli(*LONG_TRAIN, "--out", out)).startswith(busy)
    finally:
        kill(first)
    again = start(*cmd)
    try:
        wait_until(lambda: holder(out / ".avq.lock") == str(again.pid), again)
    finally:
        kill(again)


@posix_only
# Slow (a reproduction in a new process); the fast run keeps the same lock on a busy avq train directory above.
@pytest.mark.slow
def test_a_busy_reproduce_directory_is_refused_until_the_first_is_killed(tmp_path):
    cmd = ["reproduce", "--seeds", "1", "--agents", "tabular", "--no-progress", "--out", "rep"]
    first = start(*cmd, "--trials", "1000000", cwd=tmp_path)
    lock = tmp_path / ".rep.lock"  # beside the directory, which reproduce may replace as a whole
    try:
        wait_until(lambda: holder(lock) == str(first.pid), first)
        line = one_line_error(avq_cli(*cmd, "--trials", "2", cwd=tmp_path))
        assert line.startswith(f"avq: error: rep is in use by another avq process (pid {first.pid})")
    finally:
        kill(first)
    done = avq_cli(*cmd, "--trials", "2", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "rep" / "summary.json").exists()


# -- 15: Ctrl-C in a sweep ---------------------------------------------------------------------------


# Slow (a sweep in a new process, interrupted); the fast run keeps test_sweep.py's killed-and-rerun sweep.
@pytest.mark.slow
@posix_only
def test_ctrl_c_in_a_sweep_prints_the_command_that_continues_it(tmp_path):
    (tmp_path / "s.yml").write_text(yaml.safe_dump({**LONG_SWEEP, "seeds": 3, "episodes": 150}))
    cmd = ["sweep", "s.yml", "--out", "sw", "--jobs", "1", "--no-progress"]
    proc = start(*cmd, cwd=tmp_path)
    wait_until(lambda: any((tmp_path / "sw").glob("trials/*/summary.json")), proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    finished = len(list((tmp_path / "sw").glob("trials/*/summary.json")))
    assert proc.returncode == 130 and 1 <= finished < 3
    assert err.strip() == (
        f"avq: interrupted; {finished} of 3 trials finished and are kept in sw. "
        "Continue the sweep with: avq sweep s.yml --out sw --jobs 1"
    )
    again = avq_cli(*cmd, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    kept = f"{finished} finished trial{'s' if finished > 1 else ''}"
    assert again.stdout.splitlines()[0] == f"kept {kept} of 3 in sw; running the other {3 - finished}"


# -- 9: a killed sweep's workers --------------------------------------------------------------------


def _children(pid: int) -> list[int]:
    table = subprocess.run(["ps", "-A", "-o", "pid=,ppid="], capture_output=True, text=True).stdout.split()
    return [int(p) for p, pp in zip(table[::2], table[1::2]) if int(pp) == pid]


def _alive(pid: int) -> bool:
    """Running (a zombie that no one reaps has ended)."""
    state = subprocess.run(["ps", "-o", "stat=", "-p", str(pid)], capture_output=True, text=True).stdout.strip()
    return bool(state) and not state.startswith("Z")


@posix_only
def test_workers_of_a_killed_sweep_end_within_seconds(tmp_path):
    (tmp_path / "s.yml").write_text(yaml.safe_dump(LONG_SWEEP))
    proc = start("sweep", "s.yml", "--out", "sw", "--jobs", "2", "--no-progress", cwd=tmp_path)
    try:
        wait_until(lambda: len(list((tmp_path / "sw").glob("trials/*/params.json"))) == 2, proc)  # both at work
        workers = _children(proc.pid)
        assert len(workers) >= 2
    finally:
        kill(proc)
    t = time.monotonic()
    while any(_alive(w) for w in workers) and time.monotonic() - t < 5:
        time.sleep(0.1)
    left = [w for w in workers if _alive(w)]
    for w in left:
        os.kill(w, signal.SIGKILL)  # (the test's own cleanup)
    assert not left, f"alive {time.monotonic() - t:.0f} s after the sweep was killed"
