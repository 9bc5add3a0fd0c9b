"""A new user's path, scripted: a 3-D navigation task of their own in a module of the working directory, then
``avq train``, ``avq evaluate``, ``avq plot``, ``avq tune`` on a SQLite file, killed (SIGKILL) in the middle of a
trial and run again to continue the study, and ``avq train --from-study`` with the best parameters; every command
in a new process run from that directory, as the user types it. The module is the how-to's
(docs/how-to/own-task.md), so that the page's code is the code tested."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

from conftest import avq_path_env, cli_subprocess

optuna = pytest.importorskip("optuna")

HOW_TO = Path(__file__).resolve().parents[1] / "docs" / "how-to" / "own-task.md"
NAV3D = re.search(r"^```python\n(# nav3d\.py.*?)^```", HOW_TO.read_text(encoding="utf-8"), re.M | re.S).group(1)
ENV = "nav3d:user/Nav3D-v0"
#: Trials of about a second: 2 seeds x 30 episodes, 2 reports to the pruner.
TUNE = ("tune", "--env", ENV, "--agent", "avq", "--episodes", "30", "--seeds", "2", "--evaluations", "2")
TUNE += ("--n-trials", "8", "--storage", "sqlite:///study.db")


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A new directory holding ``nav3d.py``, made the current one; the module is forgotten afterwards."""
    (tmp_path / "nav3d.py").write_text(NAV3D, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    sys.modules.pop("nav3d", None)
    gym.registry.pop("user/Nav3D-v0", None)


def run_avq(*args: str, cwd: Path) -> str:
    """``avq ARGS`` in a new process from ``cwd``; its standard output (it must succeed)."""
    result = cli_subprocess(*args, cwd=cwd)
    assert result.returncode == 0, (args, result.stderr)
    return result.stdout


def _trial_lines(out: str) -> dict[int, str]:
    """The trials a run said it finished (``trial N STATE: ...``), by number; a number said twice fails."""
    said = [(int(m.group(1)), m.group(2)) for m in re.finditer(r"^trial (\d+) (\w+):", out, re.M)]
    assert len({n for n, _ in said}) == len(said), said
    return dict(said)


def _check_picture(png: Path, model: Path) -> None:
    """The picture is the model's policy: of the pixels in the actions' (lightened) colours, each action that covers
    a twentieth of the slice has its share of the slice, to within a tenth (cell borders and centres cover some
    of each colour); an action absent from the slice shows only in the legend."""
    import matplotlib.image as mpimg
    from matplotlib.colors import to_rgb

    import avq
    from avq.plotting import policy_map
    from avq.plotting.policy import ACTION_COLOURS

    image = mpimg.imread(png)[..., :3]
    assert image.shape[0] > 1000 and image.shape[1] > 1000  # 300 dpi
    view = policy_map(avq.load(model), dims=(0, 1), at={2: 0.9}, resolution=400)
    assert view.actions.shape == (400, 400) and view.at == {2: 0.9}
    share = np.bincount(view.actions.ravel(), minlength=6) / view.actions.size
    assert share.max() < 1  # more than one action on the slice
    pixels = image.shape[0] * image.shape[1]
    counts = []
    for colour in ACTION_COLOURS[:6]:
        lighter = 0.45 + 0.55 * np.array(to_rgb(colour))
        counts.append(int((np.abs(image - lighter).max(axis=-1) < 2.5 / 255).sum()))
    coloured = sum(counts)
    assert coloured > pixels / 10  # (the slice is drawn, not only the legend)
    for action, n in enumerate(counts):
        if share[action] > 0.05:
            assert abs(n / coloured - share[action]) < 0.1, (action, share[action], n / coloured)
        elif share[action] == 0:
            assert 0 < n < pixels / 200, (action, n)  # its legend patch


def _kill_in_a_trial(proc: subprocess.Popen, url: str) -> tuple[str, int]:
    """Let ``avq tune`` (``proc``) finish 2 trials, then SIGKILL it in the middle of its next one: it is stopped
    (SIGSTOP) while the study is read, so that the trial seen running is the one killed; stopped while it holds
    the file's write lock, it is let go on and read again. Returns what it printed and that trial's number."""
    watchdog = threading.Timer(300, proc.kill)
    watchdog.start()
    try:
        out = ""
        for line in proc.stdout:  # (unbuffered: the lines as they come)
            out += line
            if sum(state == "complete" for state in _trial_lines(out).values()) >= 2:
                break
        assert proc.poll() is None, ("avq tune ended before it was killed", out, proc.stderr.read())
        storage = optuna.storages.RDBStorage(url, engine_kwargs={"connect_args": {"timeout": 2}})
        study = optuna.load_study(study_name="avq-nav3d-user-Nav3D-v0", storage=storage)
        # (every parameter sampled: a trial killed while it samples holds only some, and its retry draws the rest)
        full = max(len(t.params) for t in study.get_trials(states=(optuna.trial.TrialState.COMPLETE,)))
        while True:
            proc.send_signal(signal.SIGSTOP)
            try:
                running = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,))
            except optuna.exceptions.StorageInternalError:  # (stopped while it held the file's write lock)
                running = []
            mine = [
                t.number
                for t in running
                if t.user_attrs.get("worker", "").endswith(f":{proc.pid}") and len(t.params) == full  # (training)
            ]
            if mine:
                proc.send_signal(signal.SIGKILL)
                break
            proc.send_signal(signal.SIGCONT)  # (between two trials, or the trial not yet marked or sampled)
            threading.Event().wait(0.05)
        rest, _ = proc.communicate(timeout=60)
        return out + rest, mine[0]
    finally:
        watchdog.cancel()


def test_a_new_users_path_from_their_own_task_to_a_tuned_agent(workdir):
    # train, evaluate, plot
    said = run_avq("train", "--env", ENV, "--episodes", "100", "--out", "runs/nav3d", "--no-progress", cwd=workdir)
    assert "avq on nav3d:user/Nav3D-v0 (seed 0): 100 episodes" in said and "entry '*'" in said
    assert len((workdir / "runs/nav3d/progress.csv").read_text().splitlines()) == 1 + 100
    report = json.loads(run_avq("evaluate", "runs/nav3d", "--episodes", "5", "--json", cwd=workdir))
    assert (report["env"], report["agent"], report["episodes"]) == ("user/Nav3D-v0", "avq", 5)
    assert report["mean_return"] == pytest.approx(-report["mean_steps"])  # -1 a step
    assert 0 <= report["success_rate"] <= 1 and report["success_rate"] * 5 == pytest.approx(
        round(report["success_rate"] * 5)
    )
    assert run_avq("plot", "runs/nav3d", "--dims", "0,1", "--at", "2=0.9", cwd=workdir).strip() == (
        "wrote runs/nav3d/policy_0-1.png"
    )
    _check_picture(workdir / "runs/nav3d/policy_0-1.png", workdir / "runs/nav3d/model.zip")

    # tune, killed in a trial
    url = f"sqlite:///{workdir / 'study.db'}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "avq.cli", *TUNE],
        cwd=workdir,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**avq_path_env(), "PYTHONUNBUFFERED": "1"},
    )
    first, killed = _kill_in_a_trial(proc, url)
    assert proc.returncode == -signal.SIGKILL
    from avq.tune.worker import counts

    study = optuna.load_study(study_name="avq-nav3d-user-Nav3D-v0", storage=url)
    before = counts(study)
    assert before["complete"] >= 2 and before["running"] == 1 and before["done"] < 8, before
    lost_params = study.trials[killed].params
    ran_first = _trial_lines(first)
    assert sorted(ran_first) == list(range(killed))  # it said every trial before the one killed

    # the same command again: the study continues
    second = run_avq(*TUNE, cwd=workdir)
    assert f"{before['done']} of 8 trials done" in second
    ran_second = _trial_lines(second)
    assert min(ran_second) == killed + 1  # the numbers continue
    study = optuna.load_study(study_name="avq-nav3d-user-Nav3D-v0", storage=url)
    trials = study.get_trials(deepcopy=False)
    assert [t.number for t in trials] == list(range(len(trials)))
    assert sorted([*ran_first, *ran_second, killed]) == list(range(len(trials)))  # none lost, none run twice
    after = counts(study)
    assert (after["done"], after["lost"], after["running"], after["waiting"]) == (8, 1, 0, 0), after
    assert trials[killed].state == optuna.trial.TrialState.FAIL and "error" not in trials[killed].user_attrs
    (retried,) = (t for t in trials if t.user_attrs.get("retry_of") == killed)
    assert (
        retried.params == lost_params
        and retried.number > killed
        and ran_second[retried.number]
        in (
            "complete",
            "pruned",
        )
    )
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,)):
        assert len(t.user_attrs["seed_values"]) == 2 and t.value == pytest.approx(np.mean(t.user_attrs["seed_values"]))
    assert f"trials: {after['complete']} complete, {after['pruned']} pruned" in second

    # the best parameters: exported as an entry of the defaults, and trained with
    best = study.best_trial
    assert best.value == max(t.value for t in trials if t.state == optuna.trial.TrialState.COMPLETE)
    entry = yaml.safe_load(run_avq("tune", "export", "--storage", "sqlite:///study.db", cwd=workdir))
    assert list(entry) == ["user/Nav3D-v0"]  # keyed as avq's defaults look the task up
    assert "starting from entry '*'" in entry["user/Nav3D-v0"]["reason"]
    assert {k: entry["user/Nav3D-v0"]["params"][k] for k in best.params} == pytest.approx(best.params, rel=1e-5)
    said = run_avq("train", "--from-study", "sqlite:///study.db", "--seed", "100", "--out", "runs/tuned", cwd=workdir)
    assert "avq on nav3d:user/Nav3D-v0 (seed 100): 30 episodes" in said
    config = yaml.safe_load((workdir / "runs/tuned/config.yml").read_text())
    assert (config["env"], config["agent"], config["episodes"], config["seed"]) == (ENV, "avq", 30, 100)
    assert {k: config["params"][k] for k in best.params} == pytest.approx(best.params)
    import avq

    agent = avq.load(workdir / "runs/tuned/model.zip")
    assert agent.defaults_used.key == "*" and agent.defaults_used.explicit == pytest.approx(best.params)
    assert {k: agent.get_params()[k] for k in best.params} == pytest.approx(best.params)
