"""Where a sweep's trials run: this machine (joblib processes), a Ray cluster or a Dask cluster.

Each backend takes the keyword arguments of every trial still to run and yields
``(k, result)`` pairs in the order the trials finish; a failed trial is a result
with ``status`` ``failed``, so one failure stops nothing. What a job runs is ``fn``
(default :func:`~avq.sweep.trial._safe_trial`; ``avq tune`` runs its workers the same way),
a top-level function of the job's keyword arguments that returns a dict and does not raise.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from avq.sweep.trial import _safe_trial

__all__ = ["BACKENDS", "RUNNERS", "check_backend"]

BACKENDS = ("local", "ray", "dask")


def _missing(backend: str, module: str) -> ValueError:
    return ValueError(
        f"the {backend} backend needs {module}, which is not installed: "
        f'pip install "avq[{backend}]" (from a clone of avq: pip install ".[{backend}]")'
    )


def check_backend(backend: str, address: str | None) -> None:
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


Job = Callable[[dict[str, Any]], dict[str, Any]]


def _run_local(
    jobs: list[dict[str, Any]], n_jobs: int, address: str | None, fn: Job = _safe_trial
) -> Iterator[tuple[int, dict]]:
    if n_jobs == 1:
        yield from (_indexed_trial(k, kw, fn) for k, kw in enumerate(jobs))
        return
    from joblib import Parallel, delayed

    yield from Parallel(n_jobs=n_jobs, return_as="generator_unordered")(
        delayed(_local_trial)(k, kw, os.getpid(), fn) for k, kw in enumerate(jobs)
    )


def _indexed_trial(k: int, kwargs: dict[str, Any], fn: Job = _safe_trial) -> tuple[int, dict[str, Any]]:
    return k, fn(kwargs)


def _local_trial(k: int, kwargs: dict[str, Any], sweep_pid: int, fn: Job = _safe_trial) -> tuple[int, dict[str, Any]]:
    """:func:`_indexed_trial` in a joblib worker, which ends itself when the sweep's process is gone."""
    _exit_with(sweep_pid)
    return _indexed_trial(k, kwargs, fn)


@functools.cache
def _exit_with(parent: int) -> None:
    """End this process within a second of the end of ``parent``, its parent process (once per process).

    joblib's workers outlive a sweep killed with SIGKILL: they finish their trial and
    then wait for work up to their idle timeout (300 s). A daemon thread polls
    ``os.getppid()``, which changes when the parent dies (POSIX gives orphans a new
    parent), and ends the process. The thread needs the GIL, which a compiled
    training loop holds, so a worker inside one ends when that chunk returns.
    On Windows, where a process keeps its parent's id, this does nothing.
    """
    if os.getppid() != parent:  # a worker not started by the sweep's process: nothing to watch
        return

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)  # files are written atomically, so ending here loses only the trial in progress

    threading.Thread(target=watch, name="avq-exit-with-sweep", daemon=True).start()


def _run_ray(
    jobs: list[dict[str, Any]], n_jobs: int, address: str | None, fn: Job = _safe_trial
) -> Iterator[tuple[int, dict]]:
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
        pending = [remote.remote(k, kw, fn) for k, kw in enumerate(jobs)]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if started:
            ray.shutdown()


def _run_dask(
    jobs: list[dict[str, Any]], n_jobs: int, address: str | None, fn: Job = _safe_trial
) -> Iterator[tuple[int, dict]]:
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
        futures = [client.submit(_indexed_trial, k, kw, fn, pure=False) for k, kw in enumerate(jobs)]
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


RUNNERS: dict[str, Callable[..., Iterator[tuple[int, dict]]]] = {
    "local": _run_local,
    "ray": _run_ray,
    "dask": _run_dask,
}
