"""Where a study lives: an Optuna storage from a URL, the study's identity, and trials left by a killed worker.

Any URL Optuna's :class:`~optuna.storages.RDBStorage` takes (``sqlite:///FILE``, ``postgresql://...``,
``mysql://...``), or a journal file (``journal:///FILE`` or a path ending in ``.log``). A study records
what it measures in its user attributes (:data:`IDENTITY`, :data:`OBJECTIVE`); continuing it with another
agent, task or objective is refused before anything is written.

A trial that a killed worker left ``RUNNING`` is failed and run again with the same parameters
(:func:`retry`, at most :data:`MAX_RETRIES` times): at once when its worker was a process of this machine
that no longer exists (each trial records ``host:pid``), otherwise when its heartbeat (database storages)
has been silent for :data:`GRACE_S` seconds. A worker killed between making a trial and recording its
``host:pid`` leaves a trial with neither: it is failed and run again once it is :data:`CLAIM_S` seconds old.
"""

from __future__ import annotations

import os
import re
import socket
from pathlib import Path
from typing import Any

__all__ = [
    "IDENTITY", "OBJECTIVE", "storage_url", "open_storage", "study_names", "recorded", "retry", "new_paths", "remove_new"
]  # fmt: skip

#: The study's task: continuing it with other values is refused.
IDENTITY = ("agent", "env", "env_kwargs")
#: How its trials are measured: also refused when they differ (values measured otherwise do not compare).
OBJECTIVE = ("metric", "seeds", "episodes", "timesteps", "evaluations", "eval_episodes", "fixed")
JOURNAL_SUFFIXES = (".log", ".jsonl")
MAX_RETRIES = 3
HEARTBEAT_S = 10
GRACE_S = 60
#: A live worker records its ``host:pid`` on a trial within milliseconds of making it; one left unclaimed
#: this long (seconds) was made by a worker that died.
CLAIM_S = 60
_FORMS = "sqlite:///FILE.db, postgresql://USER:PASSWORD@HOST/DB, mysql://..., journal:///FILE.log or FILE.log"


def shown(url: str) -> str:
    """``url`` with its password hidden, for messages."""
    return re.sub(r"(://[^:/@]+:)[^@]*@", r"\1***@", url)


def storage_url(storage: str | None, out: str | os.PathLike) -> str:
    """The storage's URL, checked, with file paths made absolute (workers may start elsewhere);
    the default is ``sqlite:///OUT/study.db``."""
    if storage is None:
        return f"sqlite:///{(Path(out) / 'study.db').resolve()}"
    text = storage.strip()
    if text.startswith("journal://") or ("://" not in text and text.endswith(JOURNAL_SUFFIXES)):
        path = text[len("journal://") :] if text.startswith("journal://") else text
        if not path or path == "/":
            raise ValueError(f"--storage {storage!r}: a journal needs a file, as in journal:///path/study.log")
        return f"journal://{Path(path).resolve()}"
    if "://" not in text:
        raise ValueError(f"--storage {storage!r} is not a storage URL; give one of {_FORMS}")
    scheme, rest = text.split("://", 1)
    if scheme == "sqlite" and rest.startswith("/") and not rest.startswith("//") and rest != "/:memory:":
        return f"sqlite:///{Path(rest[1:]).resolve()}"  # (sqlite:///relative/path: relative to here)
    if scheme == "postgresql":
        scheme = _postgres_driver()
    try:
        from sqlalchemy.engine import make_url

        make_url(f"{scheme}://{rest}").get_dialect()
    except Exception as exc:  # noqa: BLE001  (SQLAlchemy's errors for an unknown scheme or a missing driver)
        raise ValueError(
            f"--storage {shown(storage)!r}: unknown or unusable storage URL ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0]}); give one of {_FORMS}"
        ) from None
    return f"{scheme}://{rest}"


def new_paths(url: str) -> list[Path]:
    """What opening the file storage at ``url`` creates that does not exist yet: its file, then the directories
    above it that are missing, the nearest first (nothing for a database server); :func:`remove_new` removes
    them again."""
    for scheme in ("sqlite:///", "journal://"):
        if url.startswith(scheme):
            path = Path(url[len(scheme) :])
            return [p for p in (path, *path.parents) if not p.exists()]
    return []


def remove_new(paths: list[Path]) -> None:
    """Remove what :func:`new_paths` listed and a refused command made: the file, then each directory left
    empty (one that holds anything else is kept, with those above it)."""
    for path in paths:
        if path.is_file():
            path.unlink()
        elif path.is_dir():
            try:
                path.rmdir()
            except OSError:
                return


def _postgres_driver() -> str:
    """``postgresql`` with the driver installed: psycopg 3 (avq's extra) unless psycopg2 is there."""
    import importlib.util

    if importlib.util.find_spec("psycopg2") is None and importlib.util.find_spec("psycopg") is not None:
        return "postgresql+psycopg"
    return "postgresql"


def open_storage(url: str) -> Any:
    """The Optuna storage at ``url`` (from :func:`storage_url`); a ValueError when it cannot be opened."""
    import warnings

    import optuna

    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    optuna.logging.set_verbosity(optuna.logging.ERROR)  # (each trial says its own line)
    try:
        if url.startswith("journal://"):
            from optuna.storages.journal import JournalFileBackend

            path = Path(url[len("journal://") :])
            path.parent.mkdir(parents=True, exist_ok=True)
            return optuna.storages.JournalStorage(JournalFileBackend(str(path)))
        if url.startswith("sqlite:///"):
            Path(url[len("sqlite:///") :]).parent.mkdir(parents=True, exist_ok=True)
        return _rdb(url)
    except Exception as exc:  # noqa: BLE001  (a server that does not answer, a file that cannot be written, ...)
        raise ValueError(
            f"cannot open the storage {shown(url)}: {type(exc).__name__}: {str(exc).strip().splitlines()[0]}"
        ) from None


def _rdb(url: str, attempts: int = 5) -> Any:
    """An RDBStorage; a worker that starts beside another may meet its half-made tables and tries again."""
    import time

    import optuna
    from sqlalchemy.exc import IntegrityError, OperationalError, ProgrammingError

    engine = {"connect_args": {"timeout": 60}} if url.startswith("sqlite") else {}  # (writers wait their turn)
    stale: dict[str, Any] = {_stale_keyword(): retry}
    for attempt in range(attempts):
        try:
            return optuna.storages.RDBStorage(
                url,
                engine_kwargs=engine,
                heartbeat_interval=HEARTBEAT_S,
                grace_period=GRACE_S,
                **stale,
            )
        except (IntegrityError, OperationalError, ProgrammingError):  # (postgres: a table the other made)
            if attempt == attempts - 1:
                raise
            time.sleep(0.5 * (attempt + 1))


def _stale_keyword() -> str:
    """The name of RDBStorage's stale-trial callback (``failed_trial_callback`` before Optuna 4.9)."""
    import inspect

    import optuna

    names = inspect.signature(optuna.storages.RDBStorage).parameters
    return "heartbeat_stale_trial_callback" if "heartbeat_stale_trial_callback" in names else "failed_trial_callback"


def study_names(storage: Any) -> list[str]:
    import optuna

    return [s.study_name for s in optuna.get_all_study_summaries(storage, include_best_trial=False)]


def recorded(storage: Any, name: str) -> dict[str, Any] | None:
    """The identity and objective that study ``name`` recorded, or None when there is no such study."""
    import optuna

    if name not in study_names(storage):
        return None
    return dict(optuna.load_study(study_name=name, storage=storage).user_attrs)


def check_same(before: dict[str, Any], now: dict[str, Any], name: str, url: str, other: str = "--study-name") -> None:
    """Refuse to continue study ``name`` with values other than those it recorded; ``other``: the option that gives
    a new study its place (``--study-name`` in a storage of several, ``--out`` where the storage is its own)."""
    for key in (*IDENTITY, *OBJECTIVE):
        if key in before and _plain(before[key]) != _plain(now.get(key)):
            what = "task" if key in IDENTITY else "objective"
            raise ValueError(
                f"study {name!r} in {shown(url)} was tuned with {key} {before[key]!r}, not {now.get(key)!r} "
                f"(another {what}); give another {other} for this one, or continue that study "
                f"with {key} {before[key]!r}"
            )


def _plain(value: Any) -> Any:
    import json

    return json.loads(json.dumps(value))


def retry(study: Any, trial: Any) -> None:
    """Run a failed trial again with the same parameters (it is enqueued), up to :data:`MAX_RETRIES` times;
    also the storage's callback for a trial whose heartbeat stopped."""
    retries = int(trial.user_attrs.get("retries", 0))
    if retries >= MAX_RETRIES:
        return
    study.enqueue_trial(dict(trial.params), user_attrs={"retry_of": trial.number, "retries": retries + 1})


def worker_id() -> str:
    """``host:pid`` of this process, recorded on the trials it runs."""
    return f"{socket.gethostname()}:{os.getpid()}"


def recover_orphans(study: Any, claim: float | None = None) -> int:
    """Fail and retry the running trials whose worker was a process of this machine that is gone, and
    those older than ``claim`` seconds (default :data:`CLAIM_S`) that no worker ever claimed (its
    ``host:pid`` never recorded); their count. On Windows only the second kind; the heartbeat finds the rest."""
    import datetime

    import optuna

    host = socket.gethostname()
    now = datetime.datetime.now()
    found = 0
    for trial in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        worker = trial.user_attrs.get("worker")
        if worker is None:
            started = trial.datetime_start
            if started is None or (now - started).total_seconds() <= (CLAIM_S if claim is None else claim):
                continue
        else:
            where, _, pid = str(worker).rpartition(":")
            if os.name == "nt" or where != host or not pid.isdigit() or _alive(int(pid)):
                continue
        try:
            study.tell(trial.number, state=optuna.trial.TrialState.FAIL)
        except (ValueError, RuntimeError):
            continue  # another worker failed it first (and retries it)
        retry(study, trial)
        found += 1
    return found


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True
