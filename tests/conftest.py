"""Shared test helpers: a scripted environment whose every step is written by hand."""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces


class ScriptedEnv(gym.Env):
    """Plays back hand-written episodes, whatever the agent does, and logs its actions.

    ``episodes`` is a list of episodes; each is ``(start, steps)`` with ``start`` the
    first observation and ``steps`` a list of ``(obs, reward, terminated, truncated,
    collision)``. Episodes repeat cyclically.
    """

    def __init__(
        self,
        episodes: Sequence[tuple[Sequence[float], Sequence[tuple]]],
        n_actions: int = 2,
        low: float = -10.0,
        high: float = 10.0,
        dims: int = 2,
    ) -> None:
        self.episodes = episodes
        self.observation_space = spaces.Box(low, high, shape=(dims,), dtype=np.float64)
        self.action_space = spaces.Discrete(n_actions)
        self.actions: list[list[int]] = []
        self._ep = -1
        self._t = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._ep += 1
        self._t = 0
        self.actions.append([])
        start, _ = self.episodes[self._ep % len(self.episodes)]
        return np.asarray(start, dtype=np.float64), {}

    def step(self, action):
        self.actions[-1].append(int(action))
        _, steps = self.episodes[self._ep % len(self.episodes)]
        obs, r, term, trunc, collision = steps[self._t]
        self._t += 1
        return np.asarray(obs, dtype=np.float64), float(r), term, trunc, {"collision": collision}


@pytest.fixture
def scripted():
    return ScriptedEnv


# -- the command line, in this process or in a new one -------------------------------------------------------


@dataclass
class CliResult:
    returncode: int
    stdout: str
    stderr: str


def cli_in_process(*args: str, cwd=None) -> CliResult:
    """``avq ARGS`` through ``avq.cli.main`` in this process (fast): its exit code and what it printed."""
    from avq.cli import main

    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(args))
            except SystemExit as e:  # argparse's errors
                code = e.code
    finally:
        os.chdir(here)
    return CliResult(code, out.getvalue(), err.getvalue())


def avq_path_env() -> dict[str, str]:
    """This process's environment with the avq it imported first on ``PYTHONPATH`` (absolute), so that a new
    process runs the same avq whatever its working directory (``PYTHONPATH=src`` is relative)."""
    import avq

    here = str(Path(avq.__file__).resolve().parents[1])
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (here, os.environ.get("PYTHONPATH")) if p)}


def cli_subprocess(*args: str, cwd=None) -> CliResult:
    """``python -m avq.cli ARGS`` in a new process (the console entry point, as a user runs it; ~1-2 s each)."""
    proc = subprocess.run(
        [sys.executable, "-m", "avq.cli", *args], capture_output=True, text=True, cwd=cwd, env=avq_path_env()
    )
    return CliResult(proc.returncode, proc.stdout, proc.stderr)


#: Parametrise a test of the command line on both: the fast run checks every case in this process, the full
#: run (``pytest``) also through a new process.
CLI_RUNNERS = [
    pytest.param(cli_in_process, id="in-process"),
    pytest.param(cli_subprocess, id="subprocess", marks=pytest.mark.slow),
]
