"""Numba's compilation cache is keyed by a hash of avq's sources (avq._compile_cache): compiled code is
never stale, the cache is reused for the same sources, and old folders are pruned.

The end-to-end tests copy the package to a temporary folder and run it in subprocesses whose caches
(``XDG_CACHE_HOME``, ``NUMBA_CACHE_DIR``, ``TMPDIR``) are under ``tmp_path``: the user's cache is never
touched. The pair of modules: the cached kernel ``avq.evaluation._greedy_walks`` calls the
``inline="always"`` helper ``grid_move`` of ``avq/envs/grid_maze.py``; Numba's own check looks at
``evaluation.py`` only.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

import avq
from avq import _compile_cache

PACKAGE = Path(avq.__file__).resolve().parent

# Walks right along a 1 x 4 corridor from (0, 0) to the goal at (3, 0), at most 10 steps.
DRIVER = """
import json, sys
import numpy as np
import numba
import avq
from avq.evaluation import _greedy_walks

walls = np.zeros((1, 4), dtype=np.bool_)
policy = np.ones((1, 4), dtype=np.int64)
starts = np.zeros((1, 2), dtype=np.int64)
success, steps = _greedy_walks(walls, 3, 0, policy, starts, 10)
print(json.dumps({"success": bool(success[0]), "steps": int(steps[0]), "avq": avq.__file__,
                  "cache_dir": numba.config.CACHE_DIR,
                  "hits": sum(_greedy_walks.stats.cache_hits.values()),
                  "misses": sum(_greedy_walks.stats.cache_misses.values())}))
"""
# The goal ends the episode; the same line, of the same length, with the goal not ending it.
GOAL_LINE = "return nx, ny, GOAL_REWARD, True, False"
CHANGED_GOAL_LINE = "return nx, ny, GOAL_REWARD, False, True"


def copy_package(dest: Path) -> Path:
    """A copy of the avq package under ``dest`` (no compiled caches); returns the folder to put on the path."""
    shutil.copytree(PACKAGE, dest / "avq", ignore=shutil.ignore_patterns("__pycache__"))
    return dest


def environ(tmp_path: Path, site: Path, **extra: str) -> dict[str, str]:
    """The subprocesses' environment: the copy first on the path, every cache under ``tmp_path``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(PYTHONPATH=str(site), XDG_CACHE_HOME=str(tmp_path / "xdg"), TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir(exist_ok=True)
    env.update(extra)
    return env


def run(code: str, env: dict[str, str], cwd: Path) -> dict:
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=cwd, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def index_files(folder: Path) -> dict[Path, int]:
    """The index files of the cached kernel under ``folder``, with their modification times."""
    return {p: p.stat().st_mtime_ns for p in folder.rglob("evaluation._greedy_walks-*.nbi")}


def change_callee_only(site: Path) -> None:
    """Change ``grid_move`` (the goal no longer ends the walk), keeping its file's size and modification
    time, as an upgrade that keeps mtimes may; the caller's file ``evaluation.py`` is not touched at all."""
    callee = site / "avq" / "envs" / "grid_maze.py"
    caller = site / "avq" / "evaluation.py"
    caller_before = (caller.stat().st_mtime_ns, caller.read_bytes())
    st = callee.stat()
    text = callee.read_text()
    assert text.count(GOAL_LINE) == 1
    callee.write_text(text.replace(GOAL_LINE, CHANGED_GOAL_LINE))
    os.utime(callee, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert (callee.stat().st_size, callee.stat().st_mtime_ns) == (st.st_size, st.st_mtime_ns)
    assert (caller.stat().st_mtime_ns, caller.read_bytes()) == caller_before


def test_a_change_in_the_callees_module_is_seen(tmp_path):
    site = copy_package(tmp_path / "site")
    env = environ(tmp_path, site)
    before = run(DRIVER, env, tmp_path)
    assert Path(before["avq"]).resolve().is_relative_to(site.resolve()), before["avq"]
    assert (before["success"], before["steps"]) == (True, 3)

    change_callee_only(site)
    after = run(DRIVER, env, tmp_path)
    assert (after["success"], after["steps"]) == (False, 10), "stale compiled code: the callee's change is not seen"
    assert after["misses"] == 1 and after["hits"] == 0
    assert after["cache_dir"] != before["cache_dir"]


def test_same_sources_load_from_the_cache(tmp_path):
    site = copy_package(tmp_path / "site")
    env = environ(tmp_path, site)
    root = tmp_path / "xdg" / "avq" / "numba"

    first = run(DRIVER, env, tmp_path)
    folder = Path(first["cache_dir"])
    assert folder.parent == root and len(folder.name) == _compile_cache.HASH_LEN
    assert first["misses"] == 1 and first["hits"] == 0
    index = index_files(folder)
    assert index, list(folder.rglob("*"))
    assert not list(site.rglob("*.nbi")), "nothing is cached beside the package"

    # The same sources again: the same folder, the kernel loaded from it, its index not rewritten.
    second = run(DRIVER, env, tmp_path)
    assert second["cache_dir"] == first["cache_dir"]
    assert (second["success"], second["steps"]) == (True, 3)
    assert second["hits"] == 1 and second["misses"] == 0
    assert index_files(folder) == index


def test_users_numba_cache_dir_is_kept_and_keyed(tmp_path):
    site = copy_package(tmp_path / "site")
    theirs = tmp_path / "their-numba-cache"
    (theirs / "other-project").mkdir(parents=True)
    env = environ(tmp_path, site, NUMBA_CACHE_DIR=str(theirs))
    out = run("import json, numba, avq; print(json.dumps({'cache_dir': numba.config.CACHE_DIR}))", env, tmp_path)
    folder = Path(out["cache_dir"])
    assert folder.parent == theirs and folder.name.startswith("avq-") and folder.is_dir()
    assert (theirs / "other-project").is_dir()
    assert not (tmp_path / "xdg").exists()


def test_unwritable_cache_dir_falls_back_to_a_temporary_folder(tmp_path):
    site = copy_package(tmp_path / "site")
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the cache's parent folder should be")
    env = environ(tmp_path, site, XDG_CACHE_HOME=str(blocker))
    out = run(DRIVER, env, tmp_path)
    assert (out["success"], out["steps"]) == (True, 3)
    folder = Path(out["cache_dir"])
    assert folder.resolve().is_relative_to((tmp_path / "tmp").resolve()), folder
    assert index_files(folder)


def test_source_hash_sees_a_change_of_same_size_and_time(tmp_path):
    site = copy_package(tmp_path / "site")
    pkg = site / "avq"
    before = _compile_cache.source_hash(pkg)
    assert _compile_cache.source_hash(pkg) == before
    (pkg / "__pycache__").mkdir(exist_ok=True)
    (pkg / "__pycache__" / "x.py").write_text("ignored")
    (pkg / "notes.txt").write_text("not a source")
    assert _compile_cache.source_hash(pkg) == before
    path = pkg / "rules.py"
    st = path.stat()
    path.write_text(path.read_text().replace("dist_to_nearest > d_min", "dist_to_nearest < d_min"))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert _compile_cache.source_hash(pkg) != before
    assert len(before) == _compile_cache.HASH_LEN


@pytest.mark.parametrize("prefix", ["", "avq-"])
def test_prune_keeps_the_most_recent_and_touches_nothing_else(tmp_path, prefix):
    now = time.time()
    names = [prefix + f"{k:016x}" for k in range(6)]
    for age, name in enumerate(names):  # names[0] the most recently used
        (tmp_path / name).mkdir()
        (tmp_path / name / "f.nbi").write_text("x")
        os.utime(tmp_path / name, (now - 7200 * (age + 1),) * 2)
    others = ["notes", prefix + "0123", "avq-0000000000000000x", "0000000000000000-old"]
    for name in others:
        (tmp_path / name).mkdir()
        os.utime(tmp_path / name, (now - 10**6,) * 2)
    (tmp_path / (prefix + "f" * 16)).write_text("a file, not a folder")
    current = names[-1]  # the oldest, but the one in use

    removed = _compile_cache.prune(tmp_path, prefix, current, keep=2)

    assert sorted(p.name for p in removed) == sorted(names[2:5])
    left = {p.name for p in tmp_path.iterdir()}
    assert left == {*names[:2], current, *others, prefix + "f" * 16}

    # A folder used within the grace period is kept, however many are more recent.
    (tmp_path / names[4]).mkdir()
    os.utime(tmp_path / names[4], (now - 60,) * 2)
    assert _compile_cache.prune(tmp_path, prefix, current, keep=0, grace_s=3600) == [
        tmp_path / names[0],
        tmp_path / names[1],
    ]


def test_import_prunes_old_folders(tmp_path):
    site = copy_package(tmp_path / "site")
    root = tmp_path / "xdg" / "avq" / "numba"
    old = [root / f"{k:016x}" for k in range(_compile_cache.KEEP + 2)]
    for age, folder in enumerate(old):
        folder.mkdir(parents=True)
        os.utime(folder, (time.time() - _compile_cache.GRACE_S - 100 * (age + 1),) * 2)
    env = environ(tmp_path, site)
    out = run("import json, numba, avq; print(json.dumps({'cache_dir': numba.config.CACHE_DIR}))", env, tmp_path)
    current = Path(out["cache_dir"])
    assert {p for p in root.iterdir()} == {current, *old[: _compile_cache.KEEP - 1]}
