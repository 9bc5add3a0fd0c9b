"""``avq tune``: search an agent's parameters for a task with Optuna, in a study that many workers share.

The space searched is declared beside the agent's defaults (the ``search`` of
``avq/agents/defaults/<name>.yaml``, or a user's file); TPE proposes, seeded from ``seed``; every trial
trains on ``seeds`` seeds, reports the seed mean after each of ``evaluations`` chunks to the median
pruner, and scores the mean over seeds of ``metric``. The study lives in any Optuna storage
(:mod:`avq.tune.storage`): a SQLite file by default, a journal file, or a database server that workers on
other machines reach. Workers run here (``jobs`` processes) or on Ray or Dask, through the backends of
``avq sweep`` (:func:`avq.tune.worker.work`). Running the same command again continues the study up to
``n_trials`` trials. Optuna is the extra ``avq[tune]``.

:func:`tune` runs one, :func:`report` ranks a study's trials with their spread over seeds,
:func:`best_entry` writes the best parameters as an entry of the defaults' YAML and :func:`study_config`
gives what ``avq train --from-study`` trains with.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from pathlib import Path
from typing import Any

from avq.tune.storage import (
    IDENTITY,
    OBJECTIVE,
    check_same,
    new_paths,
    open_storage,
    recorded,
    remove_new,
    shown,
    storage_url,
    study_names,
)
from avq.tune.worker import METRICS, counts

__all__ = ["tune", "report", "best_entry", "study_config", "require_optuna", "METRICS"]


def require_optuna() -> None:
    """A ValueError that says how to install Optuna when it is missing."""
    try:
        import optuna  # noqa: F401
    except ImportError:
        raise ValueError(
            'avq tune needs Optuna, which is not installed: pip install "avq[tune]" '
            '(from a clone of avq: pip install ".[tune]")'
        ) from None


def default_name(agent: str, env: str) -> str:
    """A study's default name: ``AGENT-ENV`` with ``/`` and ``:`` as ``-``."""
    return f"{agent}-{env}".replace("/", "-").replace(":", "-")


def _study(storage: Any, name: str | None, url: str) -> str:
    """``name``, or the one study of ``storage`` when no name is given."""
    names = study_names(storage)
    if name is None and len(names) == 1:
        return names[0]
    if name is None:
        raise ValueError(
            f"{shown(url)} holds {len(names)} studies; name one with --study-name: {', '.join(names) or 'none'}"
        )
    if name not in names:
        raise ValueError(f"no study {name!r} in {shown(url)}; its studies: {', '.join(names) or 'none'}")
    return name


def tune(
    env: str | None = None,
    agent: str | None = None,
    *,
    storage: str | None = None,
    study_name: str | None = None,
    out: str | os.PathLike | None = None,
    n_trials: int = 20,
    timeout: float | None = None,
    seeds: int | None = None,
    seed: int = 0,
    episodes: int | None = None,
    timesteps: int | None = None,
    evaluations: int | None = None,
    metric: str | None = None,
    eval_episodes: int | None = None,
    env_kwargs: dict[str, Any] | None = None,
    fixed: dict[str, Any] | None = None,
    space: str | os.PathLike | None = None,
    pruner: str = "median",
    jobs: int = 1,
    backend: str = "local",
    address: str | None = None,
    log: Any = print,
) -> dict[str, Any]:
    """Tune ``agent`` on ``env`` until the study holds ``n_trials`` trials (or ``timeout`` seconds pass).

    Settings not given are taken from the study when it exists (so ``storage`` and ``study_name`` alone
    continue one), else default to 3 seeds, 300 episodes, 5 evaluations and ``final_return``. Returns the
    study's summary (:func:`summary`). Raises ValueError on bad input, before anything is written.
    """
    from avq.sweep.backends import BACKENDS, RUNNERS
    from avq.tune.worker import work

    require_optuna()
    if not isinstance(n_trials, int) or n_trials < 1:
        raise ValueError(f"--n-trials must be an integer >= 1, not {n_trials!r}: the study's number of trials")
    if timeout is not None and not timeout > 0:
        raise ValueError(f"--timeout must be a number of seconds > 0, not {timeout!r}")
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    if episodes is not None and timesteps is not None:
        raise ValueError("give episodes or timesteps, not both")
    if out is None and storage is None:
        if env is None:
            raise ValueError("--env is required (or --storage/--out of a study to continue)")
        out = Path("tune") / default_name(agent or "avq", env)
    url = storage_url(storage, out or ".")
    made = new_paths(url)
    try:
        asked = dict(env=env, agent=agent, study_name=study_name, seed=seed, seeds=seeds, episodes=episodes,
                     timesteps=timesteps, evaluations=evaluations, metric=metric, eval_episodes=eval_episodes,
                     env_kwargs=env_kwargs, fixed=fixed, space=space, backend=backend, address=address)  # fmt: skip
        study, given, searched = _open(url, out if storage is None else None, asked)
    except BaseException:  # (a refused or interrupted command leaves nothing behind; a study made meanwhile stays)
        if made and (not made[0].exists() or not _holds_a_study(url)):
            remove_new(made)
        raise
    agent, env, study_name = given["agent"], given["env"], study.study_name
    c0 = counts(study)
    log(
        f"study {study_name!r} in {shown(url)}: {c0['done']} of {n_trials} trials done; "
        f"{agent} on {env}, {given['metric']} over {len(given['seeds'])} seeds, "
        f"{given['episodes'] or given['timesteps']} {'episodes' if given['episodes'] else 'env steps'} a seed"
    )
    spec = {
        **given,
        "storage": url,
        "study_name": study_name,
        "space": {name: dataclasses.asdict(r) for name, r in searched.items()},
        "n_trials": n_trials,
        "deadline": time.time() + timeout if timeout else None,
        "seed": seed,
        "pruner": pruner,
    }
    if jobs == 1 and backend == "local":
        results = [work(spec)]
    else:
        jobs_specs = [dict(spec, worker=k) for k in range(jobs)]
        results = [r for _, r in RUNNERS[backend](jobs_specs, jobs, address, work)]
    failed = [r["error"] for r in results if r["status"] != "ok"]
    if failed:
        log(f"{len(failed)} of {len(results)} workers stopped with an error: {failed[0]}")
    written = None
    entry = best_entry(url, study_name) if out is not None else ""
    if entry:
        written = Path(out or ".") / "best.yaml"
        written.parent.mkdir(parents=True, exist_ok=True)
        written.write_text(entry, encoding="utf-8")
    summary = {"storage": url, "study_name": study_name, **counts(study), "workers_failed": len(failed)}
    return {**summary, "best_yaml": written and str(written)}


def _check_task(given: dict[str, Any], searched: dict[str, Any], where: str) -> None:
    """The space names the agent's parameters, and the agent can be made with its fixed parameters."""
    import avq.envs  # noqa: F401
    from avq.agents.registry import make_agent
    from avq.runs import make_env
    from avq.tune.space import check_space

    check_space(searched, given["agent"], given["env"], given["fixed"], where)
    probe = make_env(given["env"], given["env_kwargs"])
    try:
        make_agent(given["agent"], probe, seed=0, **given["fixed"])
    except TypeError as exc:
        raise ValueError(str(exc)) from None


def _create(store: Any, name: str, given: dict[str, Any], url: str) -> Any:
    """Study ``name``, made (maximizing) with ``given`` recorded when new; checked against it when it exists."""
    import optuna

    study = optuna.create_study(study_name=name, storage=store, direction="maximize", load_if_exists=True)
    if not study.user_attrs:
        for key in (*IDENTITY, *OBJECTIVE):
            study.set_user_attr(key, given[key])
    check_same(study.user_attrs, given, name, url)  # (a worker that made it a moment before)
    return study


def _load(storage: str, study_name: str | None) -> Any:
    import optuna

    require_optuna()
    url = storage_url(storage, ".")
    for scheme in ("sqlite:///", "journal://"):
        if url.startswith(scheme) and not Path(url[len(scheme) :]).exists():
            raise ValueError(f"no study here: {url[len(scheme) :]} does not exist; give the --storage of 'avq tune'")
    store = open_storage(url)
    name = _study(store, study_name, url)
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    return optuna.load_study(study_name=name, storage=store), url


def _finished(study: Any) -> list[Any]:
    import optuna

    done = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    return sorted(done, key=lambda t: -t.value)


def report(storage: str, study_name: str | None = None, top: int = 10) -> str:
    """The best ``top`` trials of a study, with their spread over seeds, its counts and its cost in env steps."""
    import numpy as np

    study, url = _load(storage, study_name)
    attrs, c = study.user_attrs, counts(study)
    steps = sum(int(t.user_attrs.get("env_steps", 0)) for t in study.get_trials(deepcopy=False))
    budget = f"{attrs.get('episodes')} episodes" if attrs.get("episodes") else f"{attrs.get('timesteps')} env steps"
    lines = [
        f"study {study.study_name!r} in {shown(url)}: {attrs.get('agent')} on {attrs.get('env')}"
        + (f" {attrs.get('env_kwargs')}" if attrs.get("env_kwargs") else "")
        + f", {attrs.get('metric')} mean over {len(attrs.get('seeds') or [])} seeds, {budget} a seed",
        f"trials: {c['complete']} complete, {c['pruned']} pruned, {c['failed']} failed, {c['running']} running, "
        f"{c['lost']} lost by killed workers (retried); {steps:,} env steps in all",
    ]
    best = _finished(study)[:top]
    if not best:
        return "\n".join([*lines, "no complete trial yet"])
    lines.append(f"{'rank':>4}  {'trial':>5}  {'mean':>10}  {'sd':>8}  {'min':>10}  {'max':>10}  parameters")
    for k, t in enumerate(best, 1):
        vals = np.array(t.user_attrs.get("seed_values") or [t.value], dtype=float)
        sd = f"{vals.std(ddof=1):.3g}" if len(vals) > 1 else "-"
        params = " ".join(f"{n}={_short(v)}" for n, v in t.params.items())
        lines.append(
            f"{k:>4}  {t.number:>5}  {t.value:>10.4g}  {sd:>8}  {vals.min():>10.4g}  {vals.max():>10.4g}  {params}"
        )
    lines.append(
        "a lead smaller than the spread over seeds is a tie; confirm on seeds the study did not use. "
        f"Train with the best: avq train --from-study {shown(url)} --study-name {study.study_name}"
    )
    return "\n".join(lines)


def _short(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def study_config(storage: str, study_name: str | None = None) -> dict[str, Any]:
    """What ``avq train --from-study`` trains: the study's env, env_kwargs, agent, budget and its best
    trial's parameters (on top of the study's fixed ones), in the keys of ``avq train --config``."""
    study, url = _load(storage, study_name)
    best = _finished(study)
    if not best:
        raise ValueError(f"study {study.study_name!r} in {shown(url)} has no complete trial yet; tune it further")
    attrs = study.user_attrs
    config = {k: attrs.get(k) for k in ("env", "env_kwargs", "agent", "episodes", "timesteps")}
    config["params"] = {**(attrs.get("fixed") or {}), **best[0].params}
    return {k: v for k, v in config.items() if v is not None}


def best_entry(storage: str, study_name: str | None = None) -> str:
    """The best trial's parameters as an entry of ``avq/agents/defaults/<agent>.yaml`` (YAML text), or ""
    before the first complete trial: the whole entry the trial ran with, so it stands alone."""
    import numpy as np
    import yaml

    from avq.agents.registry import AGENTS, ENTRIES, defaults_key
    from avq.envs import split_env_id

    study, _ = _load(storage, study_name)
    best = _finished(study)
    if not best:
        return ""
    t, attrs = best[0], study.user_attrs
    agent, env = attrs["agent"], attrs["env"]
    key = defaults_key(agent, env)
    vals = np.array(t.user_attrs.get("seed_values") or [t.value], dtype=float)
    budget = f"{attrs['episodes']} episodes" if attrs.get("episodes") else f"{attrs['timesteps']} env steps"
    entry: dict[str, Any] = {
        "reason": (
            f"Tuned by avq tune (study {study.study_name}, trial {t.number} of {len(study.trials)}): "
            f"{attrs['metric']} {t.value:.4g} mean over {len(vals)} seeds ({vals.min():.4g} to {vals.max():.4g}), "
            f"{budget} a seed, starting from entry {key!r}."
        ),
        "results": "how-to/tuning.md",
    }
    if ENTRIES[agent][key].cls is not AGENTS[agent][0]:
        entry["class"] = ENTRIES[agent][key].cls.__name__
    params = {**ENTRIES[agent][key].params, **(attrs.get("fixed") or {}), **t.params}
    entry["params"] = {k: (round(v, 6) if isinstance(v, float) and math.isfinite(v) else v) for k, v in params.items()}
    return yaml.safe_dump({split_env_id(env)[1]: entry}, sort_keys=False, width=110)  # (keyed as the entries are)


def _holds_a_study(url: str) -> bool:
    """Whether the storage at ``url`` holds a study (True when that cannot be told: it is kept)."""
    try:
        return bool(study_names(open_storage(url)))
    except Exception:  # noqa: BLE001  (a storage that cannot be read now is not removed)
        return True


def _open(url: str, own: str | os.PathLike | None, asked: dict[str, Any]) -> tuple[Any, dict[str, Any], dict]:
    """:func:`tune`'s study at ``url``, made or continued with the settings it records (``asked``: :func:`tune`'s
    arguments of the study), after every check of them: a ValueError before the study is made. Returns the
    study, its settings and its search space. ``own``: the ``--out`` whose own ``study.db`` is the storage,
    which holds one study (the ``best.yaml`` beside it is that study's)."""
    from avq.sweep.backends import check_backend
    from avq.sweep.config import spawn_seeds
    from avq.tune import space as spaces

    store = open_storage(url)
    names = study_names(store)
    env, study_name = asked["env"], asked["study_name"]
    if study_name is None and env is None and len(names) > 1:
        raise ValueError(f"{shown(url)} holds the studies {', '.join(names)}; name one with --study-name")
    if study_name is None and env is None and len(names) == 1:
        study_name = names[0]
    before = (recorded(store, study_name) if study_name else None) or {}
    env = env or before.get("env")
    agent = asked["agent"] or before.get("agent") or "avq"
    if env is None:
        raise ValueError(f"--env is required: {shown(url)} holds no study to continue")
    study_name = study_name or default_name(agent, env)
    if own is not None and names and study_name not in names:
        raise ValueError(
            f"{own} holds the study {names[0]!r} already, and its best.yaml; give another --out for the "
            f"study {study_name!r}, or continue that one with --out {own} alone"
        )
    before = recorded(store, study_name) or {}
    episodes, timesteps, seed = asked["episodes"], asked["timesteps"], asked["seed"]
    given: dict[str, Any] = {
        "agent": agent,
        "env": env,
        "env_kwargs": asked["env_kwargs"] if asked["env_kwargs"] is not None else before.get("env_kwargs", {}),
        "metric": asked["metric"] or before.get("metric", "final_return"),
        "seeds": list(spawn_seeds(seed, asked["seeds"])) if asked["seeds"] is not None else before.get("seeds"),
        "episodes": episodes if episodes or timesteps else before.get("episodes", None if before else 300),
        "timesteps": timesteps if episodes or timesteps else before.get("timesteps"),
        "evaluations": asked["evaluations"] or before.get("evaluations", 5),
        "eval_episodes": asked["eval_episodes"]
        if asked["eval_episodes"] is not None
        else before.get("eval_episodes", 10),
        "fixed": asked["fixed"] if asked["fixed"] is not None else before.get("fixed", {}),
    }
    given["seeds"] = given["seeds"] or list(spawn_seeds(seed, 3))
    if given["metric"] not in METRICS:
        raise ValueError(f"unknown metric {given['metric']!r}; choose one of {', '.join(METRICS)}")
    check_same(before, given, study_name, url, "--study-name" if own is None else "--out")
    space = asked["space"]
    searched = spaces.read_space(space) if space is not None else spaces.agent_space(agent)
    where = f"search space {space}" if space is not None else f"avq/agents/defaults/{agent}.yaml 'search'"
    _check_task(given, searched, where)
    check_backend(asked["backend"], asked["address"])
    return _create(store, study_name, given, url), given, searched
