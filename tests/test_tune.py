"""``avq tune``: studies of tiny trials on SQLite, a journal file and a real PostgreSQL server; workers
sharing one study (no trial lost or run twice), a killed run continued, the best parameters trained, and
bad input refused with exit 2 and the study intact."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
import yaml

from conftest import cli_in_process

optuna = pytest.importorskip("optuna")

#: A trial of about a second: tiles on MountainCar, 2 seeds x 4 episodes, 2 reports to the pruner.
TINY = ["--env", "MountainCar-v0", "--agent", "tiles", "--episodes", "4", "--seeds", "2", "--evaluations", "2"]


def _study(url: str, name: str = "tiles-MountainCar-v0"):
    from avq.tune.storage import open_storage

    return optuna.load_study(study_name=name, storage=open_storage(url))


def _check_whole(study, at_least: int, at_most: int) -> None:
    """Trial numbers 0..n-1, each once; as many trials done as asked (workers may start a few at once)."""
    from avq.tune.worker import counts

    numbers = [t.number for t in study.get_trials(deepcopy=False)]
    assert sorted(numbers) == list(range(len(numbers)))
    c = counts(study)
    assert at_least <= c["done"] <= at_most, c
    assert c["running"] == 0 and c["waiting"] == 0, c
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,)):
        assert len(t.user_attrs["seed_values"]) == 2
        assert len(t.intermediate_values) == 2  # one report to the pruner per evaluation


def _tune(*args: str, cwd=None, **popen):
    return subprocess.Popen(
        [sys.executable, "-m", "avq.cli", "tune", *args],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **popen,
    )


def _ran(outputs: list[str]) -> list[int]:
    """The trials the workers said they finished, from their lines 'trial N STATE: ...'."""
    return [int(line.split()[1]) for out in outputs for line in out.splitlines() if line.startswith("trial ")]


def _two_workers(url: str, cwd, n: int = 6) -> None:
    procs = [_tune(*TINY, "--storage", url, "--n-trials", str(n), cwd=cwd) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err
    ran = _ran([out for out, _ in outs])
    assert len(ran) == len(set(ran)), ran  # no trial run twice
    study = _study(url)
    _check_whole(study, n, n + 1)
    assert sorted(ran) == sorted(t.number for t in study.get_trials(deepcopy=False))  # none lost
    assert {t.user_attrs["worker"].rpartition(":")[2] for t in study.trials} == {str(p.pid) for p in procs}


def test_two_processes_share_one_sqlite_study(tmp_path):
    _two_workers(f"sqlite:///{tmp_path / 'study.db'}", tmp_path)


def test_tune_report_export_and_train_from_study(tmp_path):
    r = cli_in_process("tune", *TINY, "--n-trials", "3", "--out", str(tmp_path / "t"))
    assert r.returncode == 0, r.stderr
    assert "rank  trial" in r.stdout and "best.yaml" in r.stdout
    url = f"sqlite:///{tmp_path / 't' / 'study.db'}"
    study = _study(url)
    _check_whole(study, 3, 3)
    assert study.user_attrs["agent"] == "tiles" and study.user_attrs["env"] == "MountainCar-v0"
    # the exported entry: the defaults' format, and it makes the agent
    entry = yaml.safe_load((tmp_path / "t" / "best.yaml").read_text())
    from avq.agents.registry import make_agent

    (params,) = (e["params"] for e in entry.values())
    assert {"reason", "results", "params"} <= set(entry["MountainCar-v0"])
    assert make_agent("tiles", "MountainCar-v0", seed=0, **params).alpha == pytest.approx(
        study.best_params["alpha"], rel=1e-5
    )
    r = cli_in_process("tune", "export", "--storage", url)
    assert r.returncode == 0 and yaml.safe_load(r.stdout) == entry
    r = cli_in_process("tune", "report", "--out", str(tmp_path / "t"))
    assert r.returncode == 0 and "3 complete" in r.stdout
    # the same command continues the study to more trials
    r = cli_in_process("tune", "--out", str(tmp_path / "t"), "--n-trials", "4")
    assert r.returncode == 0, r.stderr
    _check_whole(_study(url), 4, 4)
    # train with the best trial's parameters
    run = tmp_path / "run"
    r = cli_in_process("train", "--from-study", url, "--out", str(run), "--episodes", "2", "--no-progress")
    assert r.returncode == 0, r.stderr
    config = yaml.safe_load((run / "config.yml").read_text())
    best = _study(url).best_params
    assert config["env"] == "MountainCar-v0" and config["agent"] == "tiles"
    assert {k: config["params"][k] for k in best} == pytest.approx(best)


def test_a_journal_file_works_too_and_without_out_says_where_the_best_entry_is(tmp_path):
    r = cli_in_process("tune", *TINY, "--n-trials", "2", "--storage", str(tmp_path / "study.log"))
    assert r.returncode == 0, r.stderr
    url = f"journal://{tmp_path / 'study.log'}"
    _check_whole(_study(url), 2, 2)
    export = f"avq tune export --storage {url} --study-name tiles-MountainCar-v0"
    assert f"best.yaml is written with --out DIR only; '{export}' prints" in r.stdout
    r = cli_in_process(*export.split()[1:])  # (the command it names works)
    assert r.returncode == 0 and "MountainCar-v0:" in r.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.log"]  # (no best.yaml, no tune/ directory)


def test_search_spaces_name_their_agents_parameters():
    from avq.agents.registry import SEARCH
    from avq.tune.space import agent_space, check_space

    for agent in ("avq", "avq-plan", "avq-sarsa", "tiles", "tabular-ps"):
        assert SEARCH[agent], agent
    for agent, raw in SEARCH.items():
        if raw:
            check_space(agent_space(agent), agent, "*", {}, agent)
    assert agent_space("avq-plan")["d_min"].log and agent_space("tiles")["n_tilings"].kind == "categorical"


@pytest.mark.parametrize("evaluations", range(1, 10))
def test_the_pruner_stops_no_trial_in_the_first_third_of_its_budget(evaluations):
    """After 5 trials that reported 0 at every evaluation, a trial that reports -1 is pruned at the first
    evaluation that comes after a third of the budget (report k comes after k / evaluations of it), not before."""
    from avq.tune.worker import PRUNER_STARTUP, _pruner

    study = optuna.create_study(direction="maximize", pruner=_pruner("median", evaluations))
    for _ in range(PRUNER_STARTUP):
        trial = study.ask()
        for step in range(1, evaluations + 1):
            trial.report(0.0, step)
        study.tell(trial, 0.0)
    trial = study.ask()
    pruned_at = None
    for step in range(1, evaluations + 1):
        trial.report(-1.0, step)
        if trial.should_prune():
            pruned_at = step
            break
    assert pruned_at is not None and pruned_at / evaluations >= 1 / 3 > (pruned_at - 1) / evaluations


@pytest.mark.parametrize(
    ("space", "says"),
    [
        ({"alpha": {"low": 0.0, "high": 1.0, "log": True}}, "log scale needs low > 0"),
        ({"alpha": {"low": 1.0, "high": 0.5}}, "low must be below high"),
        ({"alpha": {"low": 0.1, "hi": 0.5}}, "unknown key 'hi'"),
        ({"alpha": {"choices": []}}, "non-empty list"),
    ],
)
def test_bad_ranges_are_named(space, says):
    from avq.tune.space import parse_space

    with pytest.raises(ValueError, match=says):
        parse_space(space, "here")


def test_bad_input_exits_2_and_leaves_the_study(tmp_path, monkeypatch):
    out = str(tmp_path / "t")
    url = f"sqlite:///{tmp_path / 't' / 'study.db'}"
    assert cli_in_process("tune", *TINY, "--n-trials", "1", "--out", out).returncode == 0
    (tmp_path / "space.yml").write_text("search:\n  alpha: {low: 0.1, high: 1.0}\n  alhpa: {low: 0.1, high: 1.0}\n")
    cases = {
        ("--storage", "foo://bar/x"): ["foo://bar/x", "sqlite:///"],
        ("--storage", "study.sqlite"): ["study.sqlite", "not a storage URL"],
        ("--agent", "tabular-ps", "--study-name", "tiles-MountainCar-v0"): ["agent 'tiles'", "another --out"],
        ("--env", "Acrobot-v1", "--study-name", "tiles-MountainCar-v0"): ["env 'MountainCar-v0'", "another --out"],
        ("--episodes", "7"): ["episodes 4", "another objective"],
        ("--space", str(tmp_path / "space.yml")): ["'alhpa'", "not a parameter of agent 'tiles'"],
        ("--n-trials", "0"): ["--n-trials", "not 0"],
        ("--set", "alpha=0.5", "--storage", f"sqlite:///{tmp_path / 'o.db'}"): [
            "'alpha' is both searched",
            "drop the --set",
            "--space FILE.yaml",
        ],
    }
    for given, says in cases.items():
        args = list(given) if given[0] in ("--agent", "--env") else [*TINY[:4], *given]
        if "--storage" not in given:
            args += ["--out", out]
        r = cli_in_process("tune", *args)
        assert r.returncode == 2, (given, r.stdout, r.stderr)
        assert "Traceback" not in r.stderr and all(s in r.stderr for s in says), (given, r.stderr)
    study = _study(url)
    _check_whole(study, 1, 1)
    assert study.user_attrs["agent"] == "tiles" and study.user_attrs["episodes"] == 4
    assert not (tmp_path / "bar").exists() and not (tmp_path / "o.db").exists()
    monkeypatch.setitem(sys.modules, "optuna", None)
    r = cli_in_process("tune", *TINY, "--out", out)
    assert r.returncode == 2 and 'pip install "avq[tune]"' in r.stderr


def test_a_refused_command_leaves_no_file_and_an_out_holds_one_study(tmp_path):
    refused = {
        ("--agent", "no-such-agent"): "no-such-agent",
        ("--metric", "speed"): "unknown metric 'speed'",
        ("--set", "alpha=2"): "alpha",
        ("--space", str(tmp_path / "missing.yml")): "missing.yml",
    }
    for given, says in refused.items():
        args = [*TINY, *given] if given[0] != "--agent" else [*TINY[:2], *given, *TINY[4:]]
        for where in (("--out", str(tmp_path / "t" / "deeper")), ("--storage", f"sqlite:///{tmp_path / 's.db'}")):
            r = cli_in_process("tune", *args, *where, "--n-trials", "1")
            assert r.returncode == 2 and says in r.stderr and "Traceback" not in r.stderr, (given, r.stderr)
            assert sorted(p.name for p in tmp_path.iterdir()) == [], (given, where)  # (nor a directory made)

    out = tmp_path / "t"
    assert cli_in_process("tune", *TINY, "--n-trials", "1", "--out", str(out)).returncode == 0
    kept = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert set(kept) == {"study.db", "best.yaml"}
    other = cli_in_process("tune", "--env", "CartPole-v1", *TINY[2:], "--n-trials", "1", "--out", str(out))
    assert other.returncode == 2 and other.stderr.strip() == (
        f"avq: error: {out} holds the study 'tiles-MountainCar-v0' already, and its best.yaml; give another "
        f"--out for the study 'tiles-CartPole-v1', or continue that one with --out {out} alone"
    )
    objective = cli_in_process("tune", *TINY, "--metric", "eval_return", "--n-trials", "1", "--out", str(out))
    assert objective.returncode == 2 and "(another objective); give another --out for this one" in objective.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == kept
    assert cli_in_process("tune", "--n-trials", "2", "--out", str(out)).returncode == 0  # (that one, continued)
    _check_whole(_study(f"sqlite:///{out / 'study.db'}"), 2, 2)


def test_a_study_another_worker_made_meanwhile_is_kept_when_this_command_is_refused(tmp_path, monkeypatch):
    import avq.tune as tune_module

    url = f"sqlite:///{tmp_path / 'new' / 's.db'}"

    def refused_after_another_made_it(given, searched, where):  # (the other worker's study, made during the checks)
        from avq.tune.storage import open_storage

        optuna.create_study(study_name="theirs", storage=open_storage(url))
        raise ValueError("refused")

    monkeypatch.setattr(tune_module, "_check_task", refused_after_another_made_it)
    with pytest.raises(ValueError, match="refused"):
        tune_module.tune("MountainCar-v0", "tiles", storage=url, episodes=4, seeds=2, n_trials=1, log=lambda _: None)
    assert _study(url, "theirs").study_name == "theirs"


def test_an_out_of_several_studies_asks_which(tmp_path):
    url = f"sqlite:///{tmp_path / 's.db'}"
    for env in ("MountainCar-v0", "Acrobot-v1"):
        args = ["--env", env, *TINY[2:], "--n-trials", "1", "--storage", url]
        assert cli_in_process("tune", *args).returncode == 0
    again = cli_in_process("tune", "--n-trials", "2", "--storage", url)
    assert again.returncode == 2 and again.stderr.strip() == (
        f"avq: error: {url} holds the studies tiles-MountainCar-v0, tiles-Acrobot-v1; name one with --study-name"
    )


@pytest.mark.slow
def test_a_killed_run_continues(tmp_path):
    url = f"sqlite:///{tmp_path / 'study.db'}"
    proc = _tune(*TINY, "--episodes", "30", "--storage", url, "--n-trials", "8", cwd=tmp_path)
    from avq.tune.worker import counts

    deadline = time.time() + 300
    while time.time() < deadline:
        time.sleep(0.5)
        if (tmp_path / "study.db").exists():
            try:
                if counts(_study(url))["complete"] >= 2:
                    break
            except KeyError:  # (the study is not made yet)
                continue
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    before = counts(_study(url))
    assert 2 <= before["done"] < 8
    r = subprocess.run(
        [sys.executable, "-m", "avq.cli", "tune", "--storage", url, "--n-trials", "8"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    assert f"{before['done']} of 8 trials done" in r.stdout
    study = _study(url)
    _check_whole(study, 8, 8)
    lost = [t for t in study.trials if t.state == optuna.trial.TrialState.FAIL and "error" not in t.user_attrs]
    retried = [t for t in study.trials if "retry_of" in t.user_attrs]
    assert len(lost) == before["running"] and [t.user_attrs["retry_of"] for t in retried] == [t.number for t in lost]
    assert all(t.state == optuna.trial.TrialState.COMPLETE for t in retried)


@pytest.mark.filterwarnings("ignore:Heartbeat of storage")
def test_a_trial_no_worker_claimed_is_retried_once_it_is_old(tmp_path, monkeypatch):
    """A worker killed between making its trial and recording its ``host:pid`` leaves a running trial
    with no heartbeat and no owner: once it is older than CLAIM_S, the next worker fails it and runs it
    again (it waited for it for ever before)."""
    import avq.tune.storage as storage

    url = f"sqlite:///{tmp_path / 'study.db'}"
    assert cli_in_process("tune", *TINY, "--storage", url, "--n-trials", "2").returncode == 0
    study = _study(url)
    unclaimed = study.ask()
    claimed = study.ask()
    claimed.set_user_attr("worker", storage.worker_id())  # this process: alive
    running = optuna.trial.TrialState.RUNNING
    assert storage.recover_orphans(study, claim=3600) == 0  # young: a live worker may be about to claim it
    assert storage.recover_orphans(study, claim=0) == 1  # the claimed one stays: its worker lives
    trials = study.get_trials(deepcopy=False)
    assert trials[unclaimed.number].state == optuna.trial.TrialState.FAIL
    assert trials[claimed.number].state == running
    (waiting,) = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.WAITING,))
    assert waiting.user_attrs["retry_of"] == unclaimed.number
    study.tell(claimed, state=optuna.trial.TrialState.FAIL)

    again = study.ask()  # the retry itself, made and left unclaimed too
    assert again.number == waiting.number
    monkeypatch.setattr(storage, "CLAIM_S", 0)
    r = cli_in_process("tune", "--storage", url, "--n-trials", "4")
    assert r.returncode == 0, r.stderr
    trials = _study(url).get_trials(deepcopy=False)
    assert trials[again.number].state == optuna.trial.TrialState.FAIL
    (last,) = (t for t in trials if t.user_attrs.get("retry_of") == again.number)
    assert last.state == optuna.trial.TrialState.COMPLETE and last.user_attrs["retries"] == 2
    _check_whole(_study(url), 4, 4)
    assert not [t for t in trials if t.state == running]


@pytest.mark.filterwarnings("ignore:Heartbeat of storage")
def test_a_worker_with_nothing_to_start_says_what_it_waits_for(tmp_path):
    import avq.tune.storage as storage

    url = f"sqlite:///{tmp_path / 'study.db'}"
    assert cli_in_process("tune", *TINY, "--storage", url, "--n-trials", "2").returncode == 0
    study = _study(url)
    elsewhere = study.ask()
    elsewhere.set_user_attr("worker", storage.worker_id())  # this process: alive, so its trial is left alone
    r = cli_in_process("tune", "--storage", url, "--n-trials", "3", "--timeout", "2")
    assert r.returncode == 0, r.stderr
    said = [line for line in r.stdout.splitlines() if line.startswith("waiting for")]
    assert said == [
        f"waiting for trial {elsewhere.number} ({storage.worker_id()}): the study is full once they end; a trial "
        "whose worker is gone is run again (at once when it ran on this machine, else when its heartbeat stops)"
    ]
    assert _study(url).get_trials(deepcopy=False)[elsewhere.number].state == optuna.trial.TrialState.RUNNING


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["local", "dask", "ray"])
def test_workers_of_a_backend_share_one_study(tmp_path, backend):
    url = f"sqlite:///{tmp_path / 'study.db'}"
    r = cli_in_process("tune", *TINY, "--storage", url, "--n-trials", "4", "--jobs", "2", "--backend", backend)
    assert r.returncode == 0, r.stderr
    _check_whole(_study(url), 4, 5)


# -- a real PostgreSQL server ----------------------------------------------------------------------------------


def _pg_bin(name: str) -> str | None:
    import glob
    import shutil

    found = shutil.which(name) or sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"))
    return found if isinstance(found, str) else (found[-1] if found else None)


@pytest.fixture
def postgres():
    """A PostgreSQL server of its own (initdb, pg_ctl start on a free port of 127.0.0.1), and its URL."""
    import pwd
    import shutil
    import socket
    import tempfile

    pytest.importorskip("psycopg")
    if _pg_bin("initdb") is None:
        pytest.skip("PostgreSQL's server binaries are not installed (Debian: apt-get install postgresql)")
    run_as: list[str] = []
    if os.geteuid() == 0:  # initdb refuses root: run the server as the package's user
        run_as = ["runuser", "-u", "postgres", "--"]
        pwd.getpwnam("postgres")
    root = tempfile.mkdtemp(prefix="avq-pg-")
    os.chmod(root, 0o755)
    if run_as:
        shutil.chown(root, "postgres")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    data = os.path.join(root, "data")

    def pg(name: str, *args: str) -> None:
        subprocess.run([*run_as, _pg_bin(name), *args], check=True, capture_output=True, cwd=root)

    pg("initdb", "-D", data, "-A", "trust", "-U", "postgres")
    opts = f"-p {port} -k {root} -c listen_addresses=127.0.0.1"
    pg("pg_ctl", "-D", data, "-o", opts, "-l", os.path.join(root, "log"), "-w", "start")
    try:
        pg("createdb", "-h", "127.0.0.1", "-p", str(port), "-U", "postgres", "avq")
        yield f"postgresql://postgres@127.0.0.1:{port}/avq"
    finally:
        pg("pg_ctl", "-D", data, "-m", "immediate", "stop")
        shutil.rmtree(root, ignore_errors=True)


@pytest.mark.slow
def test_two_processes_share_one_postgres_study(tmp_path, postgres):
    _two_workers(postgres, tmp_path)
    r = cli_in_process("tune", "report", "--storage", postgres)
    assert r.returncode == 0 and "complete" in r.stdout
