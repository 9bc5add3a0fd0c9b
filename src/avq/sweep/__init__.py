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

import json
import os
import sys
import types
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from avq._io import atomic_write_bytes, check_output_dir, hold_directory, make_dirs
from avq.sweep.backends import BACKENDS, RUNNERS, check_backend
from avq.sweep.config import METRICS, SweepConfig, _is_int, read_sweep_config
from avq.sweep.results import _plot_curves, _rows, _write_results, report
from avq.sweep.trial import Trial, _trial_kwargs, plan_trials, run_trial  # noqa: F401  (Trial: importable here, as before)

__all__ = [
    "SweepConfig",
    "read_sweep_config",
    "plan_trials",
    "run_trial",
    "run_sweep",
    "report",
    "SweepInterrupted",
    "BACKENDS",
    "METRICS",
]


def _summary_path(out: Path, trial: Trial) -> Path:
    """The trial's ``summary.json``, written last: once it exists, the trial is finished."""
    return out / "trials" / trial.dirname / "summary.json"


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a sweep: ``finished`` of its ``total`` trials are done and kept in ``out``.

    A ``KeyboardInterrupt``, raised after ``results.csv`` was written; running the
    sweep again into ``out`` runs only the trials not finished.
    """

    def __init__(self, out: Path, finished: int, total: int) -> None:
        super().__init__(f"{finished} of {total} trials finished, kept in {out}")
        self.out, self.finished, self.total = out, finished, total


def run_sweep(
    config: str | os.PathLike | dict[str, Any] | SweepConfig,
    out: str | os.PathLike,
    *,
    backend: str = "local",
    address: str | None = None,
    jobs: int | None = None,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every trial of a sweep that has not finished yet; write ``results.csv`` and ``curves.png``.

    Args:
        config: A YAML file, a dict with the same keys, or a :class:`avq.sweep.SweepConfig`.
        out: The sweep's directory (created). Finished trials found there are skipped.
            Another process running a sweep (or a run) in ``out`` makes this one refuse.
        backend: ``local`` (joblib processes), ``ray`` or ``dask``.
        address: The cluster to use (``ray``: as for ``ray.init``; ``dask``: the scheduler's address).
            Without one, a local cluster with ``jobs`` workers is started and stopped.
        jobs: Parallel workers for ``local`` and for a cluster started here (default: the CPU count).
        progress: Show a progress bar over trials.
        log: Gets one line when finished trials found in ``out`` are kept.

    Returns:
        One row per trial, as written to ``results.csv`` (``status`` is ``ok`` or ``failed``).

    Raises:
        SweepInterrupted: on Ctrl-C, with the count of finished trials.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    if address and backend == "local":
        raise ValueError("--address is for the ray and dask backends; the local backend runs on this machine")
    if jobs is not None and not _is_int(jobs, 1):
        raise ValueError(f"jobs must be an integer >= 1, not {jobs!r}")
    cfg = config if isinstance(config, SweepConfig) else read_sweep_config(config)
    check_backend(backend, address)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out} is a file; give a directory for the sweep")
    with hold_directory(make_dirs(out)):
        if (out / "config.yml").exists() and not (out / "sweep.json").exists():
            raise ValueError(f"{out} holds a run of 'avq train'; choose another --out for the sweep")
        saved = out / "sweep.json"
        if saved.exists():
            before = json.loads(saved.read_text(encoding="utf-8"))
            if before != json.loads(json.dumps(cfg.as_dict())):
                raise ValueError(f"{out} holds a different sweep (see {saved}); choose another --out")
        else:
            check_output_dir(out, "avq sweep")
        atomic_write_bytes(saved, json.dumps(cfg.as_dict(), indent=2).encode())
        trials = plan_trials(cfg)
        results: dict[int, dict[str, Any]] = {}
        todo = []
        for t in trials:
            summary = _summary_path(out, t)
            if summary.exists():
                results[t.index] = {"status": "ok", **json.loads(summary.read_text(encoding="utf-8"))}
            else:
                todo.append(t)
        if results and log is not None:
            log(
                f"kept {len(results)} finished trial{'s' if len(results) != 1 else ''} of {len(trials)} in {out}; "
                f"running the other {len(todo)}"
            )
        n_jobs = int(jobs or os.cpu_count() or 1)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(trials), initial=len(results), unit="trial", desc=f"sweep ({backend})")
        counts = {"done": len(results), "failed": 0, "skipped": len(results)}
        try:
            if todo:
                kwargs = [_trial_kwargs(cfg, t, out) for t in todo]
                for k, result in RUNNERS[backend](kwargs, min(n_jobs, len(todo)), address):
                    results[todo[k].index] = result
                    counts["done" if result["status"] == "ok" else "failed"] += 1
                    if bar is not None:
                        bar.set_postfix(completed=counts["done"], failed=counts["failed"], refresh=False)
                        bar.update(1)
        except KeyboardInterrupt:  # (trials that finished while it stopped count too: they are kept)
            finished = sum(_summary_path(out, t).exists() for t in trials)
            raise SweepInterrupted(out, finished, len(trials)) from None
        finally:
            if bar is not None:
                bar.close()
            rows = _rows(cfg, trials, results)
            _write_results(out, cfg, rows)
        _plot_curves(out, cfg, trials, results)
        return rows


def sweep(*args: Any, **kwargs: Any) -> list[dict[str, Any]]:
    """Deprecated: :func:`run_sweep` (the old name, which was also this package's)."""
    warnings.warn(
        "avq.sweep.sweep() is deprecated and will be removed in avq 0.3; call avq.run_sweep()",
        DeprecationWarning,
        stacklevel=2,
    )
    return run_sweep(*args, **kwargs)


class _CallablePackage(types.ModuleType):
    """This package, callable as ``avq.sweep(...)`` was before the function became :func:`run_sweep`."""

    def __call__(self, *args: Any, **kwargs: Any) -> list[dict[str, Any]]:
        warnings.warn(
            "avq.sweep(...) is deprecated and will be removed in avq 0.3; call avq.run_sweep(...)",
            DeprecationWarning,
            stacklevel=2,
        )
        return run_sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage
