"""Sweeps: every (configuration, seed) pair of a grid, as independent trials, on one machine or a cluster.

A sweep is described by a YAML file (or a dict with the same keys)::

    env: avq/GridMaze-v0          # any registered Gymnasium id
    env_kwargs: {layout: lau2002} # passed to gymnasium.make (optional)
    agents: [avq-paper, tabular]  # registry names
    grid: {alpha: [0.1, 0.2], epsilon: [0.05, 0.1]}  # every combination is one configuration (optional)
    seeds: 10                     # a count (derived from root_seed, default 0) or an explicit list
    episodes: 1000                # or timesteps: N

and optionally ``params`` (agent parameters common to every configuration),
``root_seed``, ``eval_episodes`` (greedy evaluation episodes after training,
default 10), ``metric`` (the default ranking of ``avq sweep report``) and
``save_models`` (default true). A grid key ``env_kwargs.NAME`` varies an
argument of ``gymnasium.make`` instead of an agent parameter.

Every trial is :func:`run_trial`, a plain top-level function of its parameters
that writes its own directory, so that any backend can run it: ``local``
(processes through joblib), ``ray`` or ``dask``. With ``seeds`` a count, the
``s``-th seed of every configuration is the ``s``-th child of
``numpy.random.SeedSequence(root_seed).spawn``, so configurations are compared
on the same seeds, and a trial gives the same result on every backend, in any order.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math
import os
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from avq._io import ProgressLog, atomic_write_bytes

__all__ = ["SweepConfig", "read_sweep_config", "plan_trials", "run_trial", "sweep", "report", "BACKENDS",
           "METRICS"]

BACKENDS = ("local", "ray", "dask")
#: Final metrics of a trial, in ``results.csv`` order, and whether higher is better.
METRICS = {
    "final_return": True, "eval_return": True, "success_rate": True, "path_ratio": False,
    "n_cells": False, "env_steps": False, "episodes": True, "wall_s": False,
}
_KEYS = {"env", "env_kwargs", "agents", "grid", "params", "seeds", "root_seed", "episodes", "timesteps",
         "eval_episodes", "metric", "save_models"}
_ENV_PREFIX = "env_kwargs."


@dataclass(frozen=True)
class SweepConfig:
    """A checked sweep description (see the module's docstring for the keys)."""

    env: str
    agents: tuple[str, ...]
    seeds: tuple[int, ...]
    episodes: int | None = None
    timesteps: int | None = None
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list[Any]] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)
    root_seed: int = 0
    eval_episodes: int = 10
    metric: str = "final_return"
    save_models: bool = True

    def as_dict(self) -> dict[str, Any]:
        return {
            "env": self.env, "env_kwargs": self.env_kwargs, "agents": list(self.agents), "grid": self.grid,
            "params": self.params, "seeds": list(self.seeds), "root_seed": self.root_seed,
            **({"episodes": self.episodes} if self.episodes is not None else {"timesteps": self.timesteps}),
            "eval_episodes": self.eval_episodes, "metric": self.metric, "save_models": self.save_models,
        }


def _is_int(value: Any, low: int) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= low


def read_sweep_config(source: str | os.PathLike | dict[str, Any]) -> SweepConfig:
    """Read and check a sweep description; a ``ValueError`` names the offending key."""
    from avq.agents.registry import AGENTS

    where = "sweep config"
    if isinstance(source, dict):
        raw = dict(source)
    else:
        import yaml

        where = str(source)
        try:
            with open(source, encoding="utf-8") as f:
                raw = yaml.safe_load(f)  # from the stream, so that YAML errors name the file
        except OSError as exc:
            raise ValueError(f"cannot read {source}: {exc.strerror or exc}") from None
        except yaml.YAMLError as exc:
            raise ValueError(f"{source} is not valid YAML: {' '.join(str(exc).split())}") from None
        if not isinstance(raw, dict):
            raise ValueError(f"{source} must be a mapping of keys to values")

    def bad(key: str, why: str) -> ValueError:
        return ValueError(f"{where}: {key!r} {why}")

    unknown = sorted(set(raw) - _KEYS)
    if unknown:
        raise bad(unknown[0], f"is not a sweep key; known keys: {', '.join(sorted(_KEYS))}")
    if not isinstance(raw.get("env"), str) or not raw["env"]:
        raise bad("env", "is required: a registered Gymnasium id such as avq/GridMaze-v0")
    agents = raw.get("agents")
    if isinstance(agents, str):
        agents = [agents]
    if not isinstance(agents, list) or not agents or not all(isinstance(a, str) for a in agents):
        raise bad("agents", "must be a non-empty list of agent names")
    for name in agents:
        if name not in AGENTS:
            raise bad("agents", f"names an unknown agent {name!r}; known agents: {', '.join(sorted(AGENTS))}")
    for key in ("env_kwargs", "grid", "params"):
        if raw.get(key) is not None and not isinstance(raw[key], dict):
            raise bad(key, "must be a mapping")
    grid = {str(k): v for k, v in (raw.get("grid") or {}).items()}
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise bad(f"grid.{key}", "must be a non-empty list of values")
        if key in ("seed",):
            raise bad(f"grid.{key}", "cannot be swept; seeds come from 'seeds'")
    root_seed = raw.get("root_seed", 0)
    if not _is_int(root_seed, 0):
        raise bad("root_seed", f"must be an integer >= 0, not {root_seed!r}")
    seeds = raw.get("seeds", 1)
    if _is_int(seeds, 1):
        children = np.random.SeedSequence(int(root_seed)).spawn(int(seeds))
        seed_list = tuple(int(c.generate_state(1)[0]) for c in children)
    elif isinstance(seeds, list) and seeds and all(_is_int(s, 0) for s in seeds):
        if len(set(seeds)) != len(seeds):
            raise bad("seeds", "lists a seed twice")
        seed_list = tuple(int(s) for s in seeds)
    else:
        raise bad("seeds", f"must be a count >= 1 or a non-empty list of integers >= 0, not {seeds!r}")
    episodes, timesteps = raw.get("episodes"), raw.get("timesteps")
    if (episodes is None) == (timesteps is None):
        raise bad("episodes", "or 'timesteps' is required, and not both")
    for key, value in (("episodes", episodes), ("timesteps", timesteps)):
        if value is not None and not _is_int(value, 1):
            raise bad(key, f"must be an integer >= 1, not {value!r}")
    eval_episodes = raw.get("eval_episodes", 10)
    if not _is_int(eval_episodes, 0):
        raise bad("eval_episodes", f"must be an integer >= 0, not {eval_episodes!r}")
    metric = raw.get("metric", "final_return")
    if metric not in METRICS:
        raise bad("metric", f"must be one of {', '.join(METRICS)}, not {metric!r}")
    save_models = raw.get("save_models", True)
    if not isinstance(save_models, bool):
        raise bad("save_models", f"must be true or false, not {save_models!r}")
    params = dict(raw.get("params") or {})
    if "seed" in params:
        raise bad("params", "cannot set seed; seeds come from 'seeds'")
    config = SweepConfig(
        env=raw["env"], agents=tuple(agents), seeds=seed_list, episodes=episodes, timesteps=timesteps,
        env_kwargs=dict(raw.get("env_kwargs") or {}), grid=grid, params=params, root_seed=int(root_seed),
        eval_episodes=int(eval_episodes), metric=metric, save_models=save_models,
    )
    _check_configurations(config, where)
    return config


def _configurations(config: SweepConfig) -> list[tuple[str, dict[str, Any]]]:
    """Every (agent, grid point) in a fixed order: agents, then the grid's product in key order."""
    keys = list(config.grid)
    points = [dict(zip(keys, values)) for values in itertools.product(*(config.grid[k] for k in keys))]
    return [(agent, point) for agent in config.agents for point in points]


def _split(point: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A grid point as (agent parameters, environment arguments)."""
    params = {k: v for k, v in point.items() if not k.startswith(_ENV_PREFIX)}
    env_kwargs = {k[len(_ENV_PREFIX):]: v for k, v in point.items() if k.startswith(_ENV_PREFIX)}
    return params, env_kwargs


def _check_configurations(config: SweepConfig, where: str) -> None:
    """Make each configuration's agent once (on the base environment), so bad values fail before any trial."""
    from avq.agents.registry import make_agent
    from avq.experiments import make_env

    try:
        env = make_env(config.env, config.env_kwargs)
    except ValueError as exc:
        raise ValueError(f"{where}: 'env': {exc}") from None
    env_keys = {k: v[0] for k, v in config.grid.items() if k.startswith(_ENV_PREFIX)}
    if env_keys:  # the names of varied env arguments, with their first values (later ones fail as trials)
        try:
            make_env(config.env, {**config.env_kwargs, **_split(env_keys)[1]})
        except ValueError as exc:
            keys = ", ".join(f"grid.{k}" for k in env_keys)
            raise ValueError(f"{where}: {keys}: {exc}") from None
    for agent, point in _configurations(config):
        params, _ = _split(point)
        try:
            make_agent(agent, env, seed=0, **{**config.params, **params})
        except (TypeError, ValueError) as exc:
            keys = ", ".join(f"grid.{k}" for k in params) or "params"
            raise ValueError(f"{where}: agent {agent} with {_label(params) or 'its defaults'} ({keys}): {exc}") from None


def _label(point: dict[str, Any]) -> str:
    return " ".join(f"{k}={v}" for k, v in point.items())


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-." else "_" for c in text)


@dataclass(frozen=True)
class Trial:
    """One (configuration, seed) pair and where it writes."""

    index: int
    config_id: int
    agent: str
    point: dict[str, Any]
    seed_index: int
    seed: int
    dirname: str


def plan_trials(config: SweepConfig) -> list[Trial]:
    """Every trial of the sweep, numbered configuration by configuration, seed by seed."""
    out = []
    for cid, (agent, point) in enumerate(_configurations(config)):
        for s, seed in enumerate(config.seeds):
            name = f"c{cid:03d}-{_slug(agent)}-s{s:02d}"
            out.append(Trial(len(out), cid, agent, point, s, seed, name))
    return out


def run_trial(trial_dir: str, env: str, env_kwargs: dict[str, Any], agent: str, params: dict[str, Any],
              seed: int, episodes: int | None, timesteps: int | None, eval_episodes: int = 10,
              save_model: bool = True) -> dict[str, Any]:
    """Train and evaluate one agent; write ``params.json``, ``progress.csv``, ``model.zip``, ``summary.json``.

    ``summary.json`` is written last, so its presence marks a finished trial;
    a finished trial is not run again (its summary is returned).
    """
    import avq.envs  # noqa: F401  (registers avq's environments in a fresh worker)
    from avq.agents.base import PROGRESS_COLUMNS
    from avq.agents.registry import make_agent
    from avq.evaluation import evaluate_maze, evaluate_policy
    from avq.experiments import make_env

    out = Path(trial_dir)
    done = out / "summary.json"
    if done.exists():
        return json.loads(done.read_text(encoding="utf-8"))
    out.mkdir(parents=True, exist_ok=True)
    spec = {"env": env, "env_kwargs": env_kwargs, "agent": agent, "params": params, "seed": seed,
            "episodes": episodes, "timesteps": timesteps, "eval_episodes": eval_episodes}
    atomic_write_bytes(out / "params.json", json.dumps(spec, indent=2).encode())
    t0 = time.perf_counter()
    model = make_agent(agent, make_env(env, env_kwargs), seed=seed, **params)
    model.learn(total_episodes=episodes, total_timesteps=timesteps)
    progress = out / "progress.csv"
    if progress.exists():
        progress.unlink()  # left by an interrupted attempt: this attempt rewrites every row
    ProgressLog(progress, PROGRESS_COLUMNS).sync(model.history_)
    if save_model:
        model.save(out / "model.zip")
    returns = model.episode_history().get("return", np.zeros(0))
    tail = returns[-max(1, len(returns) // 10):]
    summary: dict[str, Any] = {
        "final_return": float(np.mean(tail)) if len(tail) else None,
        "eval_return": None, "success_rate": None, "path_ratio": None,
        "n_cells": int(model.n_cells), "env_steps": int(model.num_timesteps), "episodes": int(model.num_episodes),
        "wall_s": None,
    }
    if eval_episodes:
        eval_env = make_env(env, env_kwargs)
        ev = evaluate_policy(model, eval_env, n_episodes=eval_episodes, seed=seed)
        summary["eval_return"] = ev["mean_return"]
        summary["success_rate"] = ev["success_rate"]
        if hasattr(eval_env.unwrapped, "layout") and hasattr(eval_env.unwrapped.layout, "distances"):
            maze = evaluate_maze(model, make_env(env, env_kwargs))
            summary["success_rate"], summary["path_ratio"] = maze["success_rate"], maze["path_ratio"]
    summary["wall_s"] = round(time.perf_counter() - t0, 3)  # training, evaluation and saving
    atomic_write_bytes(done, json.dumps(summary, indent=2).encode())
    return summary


def _safe_trial(kwargs: dict[str, Any]) -> dict[str, Any]:
    """:func:`run_trial` that returns its error instead of raising, so one failure stops nothing."""
    try:
        return {"status": "ok", **run_trial(**kwargs)}
    except Exception as exc:  # noqa: BLE001  (any error of a trial is recorded, not raised)
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f" ({Path(last.filename).name}:{last.lineno})" if last else ""
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}{where}".replace("\n", " ")}


def _trial_kwargs(config: SweepConfig, trial: Trial, out: Path) -> dict[str, Any]:
    params, env_kwargs = _split(trial.point)
    return {
        "trial_dir": str(out / "trials" / trial.dirname), "env": config.env,
        "env_kwargs": {**config.env_kwargs, **env_kwargs}, "agent": trial.agent,
        "params": {**config.params, **params}, "seed": trial.seed, "episodes": config.episodes,
        "timesteps": config.timesteps, "eval_episodes": config.eval_episodes, "save_model": config.save_models,
    }


# -- backends --------------------------------------------------------------------------------------------

def _missing(backend: str, module: str) -> ValueError:
    return ValueError(f"the {backend} backend needs {module}, which is not installed: "
                      f"pip install \"avq[{backend}]\" (from a clone of avq: pip install \".[{backend}]\")")


def _check_backend(backend: str, address: str | None) -> None:
    """Fail before anything is written: the backend's package is missing, or its cluster is unreachable."""
    if backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise _missing("ray", "Ray") from None
    elif backend == "dask":
        try:
            import dask.distributed  # noqa: F401
        except ImportError:
            raise _missing("dask", "dask.distributed") from None
    if address and backend in ("ray", "dask") and address != "auto":
        import socket
        from urllib.parse import urlsplit

        parts = urlsplit(address if "://" in address else f"tcp://{address}")
        try:
            host, port = parts.hostname, parts.port
        except ValueError:
            host, port = None, None
        if not host or not port:
            raise ValueError(f"--address {address!r} is not host:port (or scheme://host:port)")
        try:
            socket.create_connection((host, port), timeout=10).close()
        except OSError as exc:
            raise ValueError(f"cannot reach the {backend} cluster at {address}: {exc.strerror or exc}") from None


def _run_local(jobs: list[dict[str, Any]], n_jobs: int, address: str | None) -> Iterator[tuple[int, dict]]:
    if n_jobs == 1:
        yield from (_indexed_trial(k, kw) for k, kw in enumerate(jobs))
        return
    from joblib import Parallel, delayed

    yield from Parallel(n_jobs=n_jobs, return_as="generator_unordered")(
        delayed(_indexed_trial)(k, kw) for k, kw in enumerate(jobs))


def _indexed_trial(k: int, kwargs: dict[str, Any]) -> tuple[int, dict[str, Any]]:
    return k, _safe_trial(kwargs)


def _run_ray(jobs: list[dict[str, Any]], n_jobs: int, address: str | None) -> Iterator[tuple[int, dict]]:
    try:
        import ray
    except ImportError:
        raise _missing("ray", "Ray") from None
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(num_cpus=n_jobs, include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(_indexed_trial)
        pending = [remote.remote(k, kw) for k, kw in enumerate(jobs)]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if started:
            ray.shutdown()


def _run_dask(jobs: list[dict[str, Any]], n_jobs: int, address: str | None) -> Iterator[tuple[int, dict]]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise _missing("dask", "dask.distributed") from None
    cluster = None
    if address:
        client = Client(address)
    else:
        cluster = LocalCluster(n_workers=n_jobs, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        futures = [client.submit(_indexed_trial, k, kw, pure=False) for k, kw in enumerate(jobs)]
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


_RUNNERS: dict[str, Callable[[list[dict[str, Any]], int, str | None], Iterator[tuple[int, dict]]]] = {
    "local": _run_local, "ray": _run_ray, "dask": _run_dask,
}


# -- the driver ------------------------------------------------------------------------------------------

def sweep(config: str | os.PathLike | dict[str, Any] | SweepConfig, out: str | os.PathLike, *,
          backend: str = "local", address: str | None = None, jobs: int | None = None,
          progress: bool = True) -> list[dict[str, Any]]:
    """Run every trial of a sweep that has not finished yet; write ``results.csv`` and ``curves.png``.

    Args:
        config: A YAML file, a dict with the same keys, or a :class:`SweepConfig`.
        out: The sweep's directory (created). Finished trials found there are skipped.
        backend: ``local`` (joblib processes), ``ray`` or ``dask``.
        address: The cluster to use (``ray``: as for ``ray.init``; ``dask``: the scheduler's address).
            Without one, a local cluster with ``jobs`` workers is started and stopped.
        jobs: Parallel workers for ``local`` and for a cluster started here (default: the CPU count).
        progress: Show a progress bar over trials.

    Returns:
        One row per trial, as written to ``results.csv`` (``status`` is ``ok`` or ``failed``).
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    if address and backend == "local":
        raise ValueError("--address is for the ray and dask backends; the local backend runs on this machine")
    if jobs is not None and not _is_int(jobs, 1):
        raise ValueError(f"jobs must be an integer >= 1, not {jobs!r}")
    cfg = config if isinstance(config, SweepConfig) else read_sweep_config(config)
    _check_backend(backend, address)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out} is a file; give a directory for the sweep")
    if (out / "config.yml").exists() and not (out / "sweep.json").exists():
        raise ValueError(f"{out} holds a run of 'avq train'; choose another --out for the sweep")
    saved = out / "sweep.json"
    if saved.exists():
        before = json.loads(saved.read_text(encoding="utf-8"))
        if before != json.loads(json.dumps(cfg.as_dict())):
            raise ValueError(f"{out} holds a different sweep (see {saved}); choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(saved, json.dumps(cfg.as_dict(), indent=2).encode())
    trials = plan_trials(cfg)
    results: dict[int, dict[str, Any]] = {}
    todo = []
    for t in trials:
        summary = out / "trials" / t.dirname / "summary.json"
        if summary.exists():
            results[t.index] = {"status": "ok", **json.loads(summary.read_text(encoding="utf-8"))}
        else:
            todo.append(t)
    n_jobs = int(jobs or os.cpu_count() or 1)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(trials), initial=len(results), unit="trial", desc=f"sweep ({backend})")
    counts = {"done": len(results), "failed": 0, "skipped": len(results)}
    try:
        if todo:
            kwargs = [_trial_kwargs(cfg, t, out) for t in todo]
            for k, result in _RUNNERS[backend](kwargs, min(n_jobs, len(todo)), address):
                results[todo[k].index] = result
                counts["done" if result["status"] == "ok" else "failed"] += 1
                if bar is not None:
                    bar.set_postfix(completed=counts["done"], failed=counts["failed"], refresh=False)
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        rows = _rows(cfg, trials, results)
        _write_results(out, cfg, rows)
    _plot_curves(out, cfg, trials, results)
    return rows


def _rows(cfg: SweepConfig, trials: list[Trial], results: dict[int, dict[str, Any]]) -> list[dict[str, Any]]:
    keys = list(cfg.grid)
    rows = []
    for t in trials:
        if t.index not in results:
            continue
        r = results[t.index]
        row: dict[str, Any] = {"trial": t.dirname, "config": t.config_id, "agent": t.agent,
                               "seed_index": t.seed_index, "seed": t.seed}
        row.update({f"config/{k}": t.point[k] for k in keys})
        row["status"] = r["status"]
        row.update({m: r.get(m) for m in METRICS})
        row["error"] = r.get("error", "")
        rows.append(row)
    return rows


def _write_results(out: Path, cfg: SweepConfig, rows: list[dict[str, Any]]) -> None:
    columns = ["trial", "config", "agent", "seed_index", "seed", *(f"config/{k}" for k in cfg.grid), "status",
               *METRICS, "error"]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in columns})
    atomic_write_bytes(out / "results.csv", buf.getvalue().encode())


def _config_label(agent: str, point: dict[str, Any]) -> str:
    return f"{agent} {_label(point)}".strip()


def _plot_curves(out: Path, cfg: SweepConfig, trials: list[Trial], results: dict[int, dict[str, Any]]) -> bool:
    """Return per episode, mean and 95% interval over seeds, one line per configuration."""
    from avq.plotting import plot_learning_curves

    curves: dict[str, list[np.ndarray]] = {}
    for t in trials:
        if results.get(t.index, {}).get("status") != "ok":
            continue
        path = out / "trials" / t.dirname / "progress.csv"
        with open(path, encoding="utf-8") as f:
            returns = np.array([float(r["return"]) for r in csv.DictReader(f)])
        curves.setdefault(_config_label(t.agent, t.point), []).append(returns)
    path = out / "curves.png"
    curves = {k: runs for k, runs in curves.items() if min(len(c) for c in runs) > 0}
    if not curves:
        if path.exists():
            path.unlink()  # a figure of an earlier state of the sweep would mislead
        return False
    # At most the 10 best configurations by the sweep's metric, so that the figure stays readable.
    note = ""
    if len(curves) > 10:
        higher = METRICS[cfg.metric]
        score: dict[str, list[float]] = {}
        for t in trials:
            value = results.get(t.index, {}).get(cfg.metric)
            if value is not None:
                score.setdefault(_config_label(t.agent, t.point), []).append(float(value))
        ranked = sorted(curves, key=lambda k: -np.mean(score.get(k, [-math.inf])) if higher
                        else np.mean(score.get(k, [math.inf])))
        curves = {k: curves[k] for k in ranked[:10]}
        note = f", the 10 best of {len(ranked)} configurations by {cfg.metric}"
    # Each configuration is drawn over the episodes all its seeds have.
    plot_learning_curves(curves, path, ylabel="return per episode", xlabel="episode",
                         title=f"{cfg.env}: return per episode\n(mean, 95% t-interval over seeds{note})")
    return True


# -- the report ------------------------------------------------------------------------------------------

def report(out: str | os.PathLike, metric: str | None = None) -> str:
    """The configurations of a finished (or partial) sweep ranked by ``metric``, as a table."""
    from avq.plotting import mean_ci95

    out = Path(out)
    path = out / "results.csv"
    if not path.exists():
        raise ValueError(f"{out}: no results.csv here; is this a directory written by 'avq sweep'?")
    saved = json.loads((out / "sweep.json").read_text(encoding="utf-8")) if (out / "sweep.json").exists() else {}
    metric = metric or saved.get("metric", "final_return")
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose one of {', '.join(METRICS)}")
    with open(path, encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    groups: dict[str, dict[str, Any]] = {}
    for row in rows:
        label = " ".join([row["agent"], *(f"{k[7:]}={v}" for k, v in row.items() if k.startswith("config/"))])
        g = groups.setdefault(label, {"values": [], "failed": 0, "trials": 0})
        g["trials"] += 1
        if row["status"] != "ok":
            g["failed"] += 1
        elif row[metric] not in ("", None):
            g["values"].append(float(row[metric]))
    higher = METRICS[metric]
    ranked = []
    for label, g in groups.items():
        vals = np.array(g["values"])
        mean, half = (mean_ci95(vals[:, None]) if len(vals) else (np.array([math.nan]), np.array([math.nan])))
        ranked.append((label, float(mean[0]), float(half[0]), vals, g))
    ranked.sort(key=lambda r: (math.isnan(r[1]), -r[1] if higher else r[1]))
    width = max([len("configuration")] + [len(r[0]) for r in ranked])
    head = f"{'rank':>4}  {'configuration':<{width}}  {metric + ' mean':>16}  {'± 95%':>9}  {'min':>9}  {'max':>9}  {'ok':>3}  {'failed':>6}"
    lines = [f"{out}: {len(rows)} trials, ranked by {metric} ({'higher' if higher else 'lower'} is better)", head,
             "-" * len(head)]
    for k, (label, mean, half, vals, g) in enumerate(ranked, 1):
        lo = f"{vals.min():.4g}" if len(vals) else "-"
        hi = f"{vals.max():.4g}" if len(vals) else "-"
        spread = f"{half:.3g}" if len(vals) >= 2 else "-"
        lines.append(f"{k:>4}  {label:<{width}}  {mean:>16.4g}  {spread:>9}  {lo:>9}  {hi:>9}  "
                     f"{len(vals):>3}  {g['failed']:>6}")
    return "\n".join(lines)
