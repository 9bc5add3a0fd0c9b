"""A tuning worker: it takes trials from a shared study until the study holds enough, or time is up.

:func:`work` is a plain top-level function of a dict (the backends of ``avq sweep`` run it as a job), so
that any number of workers, here or on a cluster, share one study through its storage. A trial trains the
agent on every seed in :data:`~avq.tune.worker` "evaluations" chunks; after each chunk the mean over seeds
of the chunk's mean return is reported to the pruner, which stops a trial that trails the median of the
others at that point. The trial's value is the mean over seeds of the metric at the end.
"""

from __future__ import annotations

import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from avq.tune.space import Range
from avq.tune.storage import open_storage, recover_orphans, worker_id

__all__ = ["work", "counts", "METRICS"]

#: The metrics a study can maximize (higher is better).
METRICS = ("final_return", "eval_return", "success_rate")
#: TPE's first trials are random; the pruner compares from its 5th trial on.
STARTUP_TRIALS = 8
PRUNER_STARTUP = 5
POLL_S = 1.0


def _sampler(seed: int) -> Any:
    """TPE whose draws for trial ``n`` come from a generator seeded by (``seed``, ``n``): one worker
    repeats its study exactly, and workers (or a restarted run) never draw the same random trials."""
    import optuna

    class SeededByTrial(optuna.samplers.BaseSampler):
        def __init__(self) -> None:
            self._tpe: dict[int, optuna.samplers.TPESampler] = {}

        def _for(self, trial: Any) -> optuna.samplers.TPESampler:
            if trial.number not in self._tpe:
                state = int(np.random.SeedSequence([seed, trial.number]).generate_state(1)[0])
                self._tpe = {
                    trial.number: optuna.samplers.TPESampler(
                        seed=state, n_startup_trials=STARTUP_TRIALS, constant_liar=True
                    )
                }
            return self._tpe[trial.number]

        def infer_relative_search_space(self, study: Any, trial: Any) -> dict[str, Any]:
            return self._for(trial).infer_relative_search_space(study, trial)

        def sample_relative(self, study: Any, trial: Any, search_space: dict[str, Any]) -> dict[str, Any]:
            return self._for(trial).sample_relative(study, trial, search_space)

        def sample_independent(self, study: Any, trial: Any, param_name: str, param_distribution: Any) -> Any:
            return self._for(trial).sample_independent(study, trial, param_name, param_distribution)

        def before_trial(self, study: Any, trial: Any) -> None:
            self._for(trial).before_trial(study, trial)

        def after_trial(self, study: Any, trial: Any, state: Any, values: Any) -> None:
            self._for(trial).after_trial(study, trial, state, values)

    return SeededByTrial()


def _pruner(kind: str, evaluations: int) -> Any:
    import optuna

    if kind == "none":
        return optuna.pruners.NopPruner()
    # Report k comes after k / evaluations of the budget: none in its first third is pruned.
    return optuna.pruners.MedianPruner(n_startup_trials=PRUNER_STARTUP, n_warmup_steps=-(-evaluations // 3))


def counts(study: Any) -> dict[str, int]:
    """The study's trials by state; ``done`` counts those that measured something (complete, pruned, or
    failed by the agent), not those failed by a killed worker (retried)."""
    import optuna

    state = optuna.trial.TrialState
    out = {"complete": 0, "pruned": 0, "failed": 0, "lost": 0, "running": 0, "waiting": 0}
    for t in study.get_trials(deepcopy=False):
        if t.state == state.COMPLETE:
            out["complete"] += 1
        elif t.state == state.PRUNED:
            out["pruned"] += 1
        elif t.state == state.FAIL:
            out["failed" if "error" in t.user_attrs else "lost"] += 1
        elif t.state == state.RUNNING:
            out["running"] += 1
        elif t.state == state.WAITING:
            out["waiting"] += 1
    out["done"] = out["complete"] + out["pruned"] + out["failed"]
    return out


def _chunks(budget: int, n: int) -> list[int]:
    """``budget`` split into at most ``n`` nearly equal positive parts."""
    edges = np.linspace(0, budget, min(n, budget) + 1).round().astype(int)
    return [int(b) for b in np.diff(edges) if b > 0]


def _objective(trial: Any, spec: dict[str, Any], space: dict[str, Range]) -> float:
    trial.set_user_attr("worker", worker_id())  # first: a trial no worker claims is taken for an orphan
    import optuna

    import avq.envs  # noqa: F401  (registers avq's environments in a fresh worker)
    from avq.agents.registry import make_agent
    from avq.runs import make_env

    params = {name: r.suggest(trial) for name, r in space.items()}
    try:
        agents = [
            make_agent(spec["agent"], make_env(spec["env"], spec["env_kwargs"]), seed=s, **spec["fixed"], **params)
            for s in spec["seeds"]
        ]
        for step, size in enumerate(_chunks(spec["episodes"] or spec["timesteps"], spec["evaluations"]), 1):
            means = []
            for agent in agents:
                before = len(agent.episode_history().get("return", ()))
                agent.learn(total_episodes=size) if spec["episodes"] else agent.learn(total_timesteps=size)
                returns = agent.episode_history().get("return", np.zeros(0))
                new = returns[before:] if len(returns) > before else returns[-1:]
                means.append(float(np.mean(new)) if len(new) else np.nan)
            trial.set_user_attr("env_steps", int(sum(a.num_timesteps for a in agents)))
            if np.isfinite(means).all():
                trial.report(float(np.mean(means)), step)
                if trial.should_prune():
                    raise optuna.TrialPruned(f"pruned after evaluation {step}")
        values = [_measure(agent, spec, seed) for agent, seed in zip(agents, spec["seeds"])]
        trial.set_user_attr("seed_values", values)
        trial.set_user_attr("n_cells", [int(a.n_cells) for a in agents])
        if not np.isfinite(values).all():
            raise ValueError(f"{spec['metric']} is undefined for some seed: {values}")
        return float(np.mean(values))
    except optuna.TrialPruned:
        raise
    except Exception as exc:
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f" ({Path(last.filename).name}:{last.lineno})" if last else ""
        trial.set_user_attr("error", f"{type(exc).__name__}: {exc}{where}".replace("\n", " ")[:500])
        raise


def _measure(agent: Any, spec: dict[str, Any], seed: int) -> float:
    from avq.sweep.trial import final_return

    if spec["metric"] == "final_return":
        value = final_return(agent)
        return np.nan if value is None else value
    from avq.evaluation import evaluate_policy
    from avq.runs import make_env

    ev = evaluate_policy(
        agent, make_env(spec["env"], spec["env_kwargs"]), n_eval_episodes=spec["eval_episodes"], seed=seed
    )
    key = "mean_return" if spec["metric"] == "eval_return" else "success_rate"
    return np.nan if ev[key] is None else float(ev[key])


def _say(study: Any, trial: Any) -> None:
    """One line per finished trial."""
    state = trial.state.name.lower()
    if trial.state.name == "COMPLETE":
        seeds = trial.user_attrs.get("seed_values") or []
        spread = f" (seeds {min(seeds):.4g} .. {max(seeds):.4g})" if seeds else ""
        what = f"{trial.value:.4g}{spread}"
    elif trial.state.name == "PRUNED":
        what = f"after evaluation {trial.last_step}"
    else:
        what = trial.user_attrs.get("error", "")
    steps = trial.user_attrs.get("env_steps")
    cost = f", {steps:,} env steps" if steps else ""
    print(f"trial {trial.number} {state}: {what}{cost}", flush=True)


def _waiting(study: Any) -> str:
    """What a worker with no trial left to start waits for: the running trials and their workers."""
    import optuna

    running = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,))
    held = ", ".join(f"{t.number} ({t.user_attrs.get('worker', 'no worker yet')})" for t in running)
    return (
        f"waiting for trial{'s' * (len(running) > 1)} {held}: the study is full once they end; "
        "a trial whose worker is gone is run again (at once when it ran on this machine, else when its heartbeat stops)"
    )


def work(spec: dict[str, Any]) -> dict[str, Any]:
    """Run trials of the study ``spec`` names until it holds ``n_trials`` done ones or the deadline passes;
    returns ``status``, the ``trials`` it ran (their numbers) and, when it failed, the ``error``."""
    ran: list[int] = []
    try:
        _work(spec, ran)
    except Exception as exc:  # noqa: BLE001  (a worker's error is returned, as a sweep trial's is)
        return {"status": "failed", "trials": ran, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    return {"status": "ok", "trials": ran}


def _work(spec: dict[str, Any], ran: list[int]) -> None:
    import optuna

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    space = {name: Range(**r) for name, r in spec["space"].items()}
    study = optuna.load_study(
        study_name=spec["study_name"],
        storage=open_storage(spec["storage"]),
        sampler=_sampler(spec["seed"]),
        pruner=_pruner(spec["pruner"], spec["evaluations"]),
    )
    deadline = spec.get("deadline")

    def objective(trial: Any) -> float:
        ran.append(trial.number)
        return _objective(trial, spec, space)

    waiting_said = False
    while deadline is None or time.time() < deadline:
        recover_orphans(study)
        c = counts(study)
        if c["done"] >= spec["n_trials"]:
            return
        if c["done"] + c["running"] >= spec["n_trials"] and not c["waiting"]:
            if not waiting_said:
                print(_waiting(study), flush=True)
                waiting_said = True
            optuna.storages.fail_stale_trials(study)  # (others' trials: finished, or failed and retried, soon)
            time.sleep(POLL_S)
            continue
        study.optimize(objective, n_trials=1, catch=(Exception,), callbacks=[_say], gc_after_trial=False)
