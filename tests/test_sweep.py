"""Sweeps: the local backend end to end, Ray and Dask clusters giving the same results, resume, failures."""

from __future__ import annotations

import csv
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import avq
from avq.sweep import plan_trials, read_sweep_config, report, run_sweep

from conftest import CLI_RUNNERS

CONFIG = {
    "env": "avq/GridMaze-v0",
    "agents": ["avq-paper", "tabular"],
    "grid": {"alpha": [0.3, 0.5]},
    "seeds": 2,
    "episodes": 30,
    "eval_episodes": 3,
}


def _table(out: Path) -> list[dict[str, str]]:
    """results.csv without the wall-clock column."""
    with open(out / "results.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        row.pop("wall_s")
    return rows


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "local"
    rows = run_sweep(CONFIG, out, backend="local", jobs=2, progress=False)
    return out, rows


def test_local_sweep_writes_every_trial_and_the_driver_files(local_run):
    out, rows = local_run
    assert len(rows) == 8 and all(r["status"] == "ok" for r in rows)
    table = _table(out)
    assert [r["trial"] for r in table] == [t.dirname for t in plan_trials(read_sweep_config(CONFIG))]
    assert {r["config/alpha"] for r in table} == {"0.3", "0.5"}
    assert {(r["agent"], r["config/alpha"]) for r in table} == {
        (a, x) for a in ("avq-paper", "tabular") for x in ("0.3", "0.5")
    }
    for trial in (out / "trials").iterdir():
        assert {p.name for p in trial.iterdir() if not p.name.startswith(".")} == {
            "params.json",
            "progress.csv",
            "model.zip",
            "summary.json",
        }
        assert len((trial / "progress.csv").read_text().splitlines()) == 31
    assert (out / "curves.png").read_bytes().startswith(b"\x89PNG")
    # A trial's model is the one run_trial trained: reload it and compare with a fresh run.
    row = table[0]
    model = avq.load(out / "trials" / row["trial"] / "model.zip")
    again = avq.make_agent(row["agent"], model.env, seed=int(row["seed"]), alpha=float(row["config/alpha"]))
    again.learn(total_episodes=30)
    assert np.array_equal(model.q_, again.q_) and int(row["env_steps"]) == again.num_timesteps


def test_seeds_come_from_the_root_seed_and_are_shared_by_configurations(local_run):
    children = np.random.SeedSequence(0).spawn(2)
    expected = [int(c.generate_state(1)[0]) for c in children]
    table = _table(local_run[0])
    for row in table:
        assert int(row["seed"]) == expected[int(row["seed_index"])]
    explicit = read_sweep_config({**CONFIG, "seeds": [7, 9]})
    assert explicit.seeds == (7, 9)
    assert read_sweep_config({**CONFIG, "root_seed": 5}).seeds != read_sweep_config(CONFIG).seeds


def test_rerun_skips_finished_trials_and_gives_the_same_table(local_run, tmp_path):
    out, _ = local_run
    stamp = {p: p.stat().st_mtime_ns for p in (out / "trials").rglob("summary.json")}
    run_sweep(CONFIG, out, jobs=2, progress=False)
    assert {p: p.stat().st_mtime_ns for p in (out / "trials").rglob("summary.json")} == stamp
    with pytest.raises(ValueError, match="different sweep"):
        run_sweep({**CONFIG, "episodes": 31}, out, progress=False)


def test_report_ranks_configurations_with_their_spread(local_run):
    text = report(local_run[0], metric="success_rate")
    lines = text.splitlines()
    assert "ranked by success_rate (higher is better)" in lines[0]
    body, note = lines[3:-1], lines[-1]
    assert len(body) == 4 and all(line.split()[-2:] == ["2", "0"] for line in body)
    assert note.startswith("* from fewer than 5 seeds")  # (2 seeds each: every interval is marked wide)
    means = [float(line.split()[3]) for line in body]
    assert means == sorted(means, reverse=True)
    table = _table(local_run[0])
    best = [r for r in table if f"{r['agent']} alpha={r['config/alpha']}" in body[0]]
    assert np.isclose(np.mean([float(r["success_rate"]) for r in best]), means[0], rtol=1e-3)
    with pytest.raises(ValueError, match="unknown metric"):
        report(local_run[0], metric="speed")


def test_a_failing_trial_is_recorded_and_the_others_finish(tmp_path):
    config = {**CONFIG, "agents": ["tabular"], "grid": {"env_kwargs.layout": ["open5", "no-such-layout"]}, "seeds": 1}
    rows = run_sweep(config, tmp_path / "s", jobs=1, progress=False)
    by = {r["config/env_kwargs.layout"]: r for r in rows}
    assert by["open5"]["status"] == "ok" and by["open5"]["success_rate"] is not None
    assert by["no-such-layout"]["status"] == "failed" and "no-such-layout" in by["no-such-layout"]["error"]
    table = {r["config/env_kwargs.layout"]: r for r in _table(tmp_path / "s")}
    assert table["no-such-layout"]["status"] == "failed" and "no-such-layout" in table["no-such-layout"]["error"]
    cfg = tmp_path / "f.yml"
    cfg.write_text(yaml.safe_dump(config))
    proc = subprocess.run(
        [sys.executable, "-m", "avq.cli", "sweep", str(cfg), "--out", str(tmp_path / "s"), "--no-progress"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1 and "1 failed" in proc.stdout and "no-such-layout" in proc.stderr


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"env": None}, "'env' is required"),
        ({"agents": ["nope"]}, "unknown agent 'nope'"),
        ({"agents": []}, "'agents' must be a non-empty list"),
        ({"grid": {"alpha": 0.3}}, "'grid.alpha' must be a non-empty list"),
        ({"grid": {"alpha": [0.3, 7.0]}}, "alpha must be in"),
        ({"grid": {"colour": [1]}}, "colour"),
        ({"seeds": 0}, "'seeds' must be a count"),
        ({"seeds": [1, 1]}, "lists a seed twice"),
        ({"timesteps": 100}, "not both"),
        ({"episodes": None}, "'episodes' or 'timesteps' is required"),
        ({"episodes": -2}, "'episodes' must be an integer >= 1"),
        ({"metric": "speed"}, "'metric' must be one of"),
        ({"sedes": 3}, "'sedes' is not a sweep key"),
        ({"env": "NoSuchEnv-v9"}, "'env'"),
        ({"params": {"seed": 1}}, "cannot set seed"),
    ],
)
@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
def test_config_errors_name_the_key(change, needle, tmp_path, run_cli):
    config = {k: v for k, v in {**CONFIG, **change}.items() if v is not None}
    with pytest.raises(ValueError, match=needle):
        read_sweep_config(config)
    cfg = tmp_path / "bad.yml"
    cfg.write_text(yaml.safe_dump(config))
    proc = run_cli("sweep", str(cfg), "--out", str(tmp_path / "o"))
    key = needle.split("'")[1] if "'" in needle else needle
    assert proc.returncode == 2 and key in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["sweep", "missing.yml", "--out", "o"], "no such sweep config"),
        (["sweep", "c.yml"], "--out DIR is required"),
        (["sweep", "c.yml", "--out", "o", "--backend", "spark"], "invalid choice"),
        (["sweep", "c.yml", "--out", "o", "--address", "x:1"], "--address is for the ray and dask"),
        (["sweep", "report"], "usage: avq sweep report DIR"),
        (["sweep", "report", "nowhere"], "no results.csv"),
        (["sweep", "c.yml", "--out", "o", "--jobs", "0"], "--jobs must be >= 1"),
    ],
)
@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
def test_cli_mistakes_exit_2(args, needle, tmp_path, run_cli):
    (tmp_path / "c.yml").write_text(yaml.safe_dump(CONFIG))
    proc = run_cli(*args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert needle in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_a_missing_backend_names_its_extra(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now fails, as when it is not installed
    with pytest.raises(ValueError, match=r'pip install "avq\[ray\]"'):
        run_sweep(CONFIG, tmp_path / "o", backend="ray", progress=False)


# Slow (starts a Ray cluster); the fast run keeps the same check on a Dask cluster below and the local sweep.
@pytest.mark.slow
def test_ray_cluster_gives_the_local_results(local_run, tmp_path):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)  # a real local cluster
    try:
        assert ray.is_initialized()
        run_sweep(CONFIG, tmp_path / "ray", backend="ray", progress=False)
    finally:
        ray.shutdown()
    assert _table(tmp_path / "ray") == _table(local_run[0])


def test_dask_cluster_gives_the_local_results(local_run, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        run_sweep(CONFIG, tmp_path / "dask", backend="dask", address=cluster.scheduler_address, progress=False)
    assert _table(tmp_path / "dask") == _table(local_run[0])


def test_a_sweep_killed_and_rerun_equals_an_uninterrupted_one(local_run, tmp_path):
    cfg = tmp_path / "c.yml"
    cfg.write_text(yaml.safe_dump(CONFIG))
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "avq.cli", "sweep", str(cfg), "--out", str(out), "--jobs", "1", "--no-progress"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        t = time.monotonic()
        while len(list(out.glob("trials/*/summary.json"))) < 2:
            assert time.monotonic() - t < 120 and proc.poll() is None, "the sweep ended before it was killed"
            time.sleep(0.01)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finished = len(list(out.glob("trials/*/summary.json")))
    assert 2 <= finished < 8, finished
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert _table(out) == _table(local_run[0])


def test_an_unreachable_cluster_or_a_grid_env_typo_fails_before_anything_is_written(tmp_path):
    import socket

    with socket.socket() as s:  # a port that nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    for backend in ("ray", "dask"):
        with pytest.raises(ValueError, match=f"cannot reach the {backend} cluster"):
            run_sweep(CONFIG, tmp_path / backend, backend=backend, address=f"127.0.0.1:{port}", progress=False)
        assert not (tmp_path / backend).exists()
    with pytest.raises(ValueError, match="grid.env_kwargs.layot"):
        read_sweep_config({**CONFIG, "grid": {"env_kwargs.layot": ["open5"]}})


def test_when_no_trial_succeeded_a_stale_figure_is_removed_and_not_claimed(tmp_path):
    from avq.sweep import _plot_curves

    cfg = read_sweep_config(CONFIG)
    (tmp_path / "curves.png").write_bytes(b"an older figure")
    assert _plot_curves(tmp_path, cfg, plan_trials(cfg), {}) is False
    assert not (tmp_path / "curves.png").exists()


def test_sweeps_and_training_runs_keep_out_of_each_others_directories(local_run, tmp_path):
    from avq.runs import train

    with pytest.raises(ValueError, match="holds a sweep"):
        train("avq/GridMaze-v0", "tabular", episodes=2, out=local_run[0], progress=False)
    run = tmp_path / "run"
    train("avq/GridMaze-v0", "tabular", episodes=2, out=run, progress=False)
    with pytest.raises(ValueError, match="holds a run of 'avq train'"):
        run_sweep(CONFIG, run, progress=False)


def test_the_old_name_avq_sweep_still_runs_a_sweep_with_a_deprecation_warning(tmp_path):
    import avq

    assert callable(avq.run_sweep) and avq.run_sweep is avq.sweep.run_sweep
    with pytest.warns(DeprecationWarning, match=r"avq.run_sweep"):
        old = avq.sweep(CONFIG, tmp_path / "old", jobs=1, progress=False)
    with pytest.warns(DeprecationWarning, match=r"avq.run_sweep"):
        avq.sweep.sweep(CONFIG, tmp_path / "older", jobs=1, progress=False)
    new = avq.run_sweep(CONFIG, tmp_path / "new", jobs=1, progress=False)
    drop = ("wall_s", "trial_dir")
    assert [{k: v for k, v in r.items() if k not in drop} for r in old] == [
        {k: v for k, v in r.items() if k not in drop} for r in new
    ]
