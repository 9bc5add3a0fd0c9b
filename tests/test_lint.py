"""The linters pass: ``ruff check`` and ``ruff format --check`` on the repository, ``mypy`` on the whole package.

Their settings are in pyproject.toml; the tools come with the ``test`` extra, so the README's test
command (``pip install ".[test]" && pytest``, all that CI runs) runs them too.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(*args: str) -> None:
    """Run ``python -m <tool> ...`` from the repository's root; fail with its output unless it exits 0."""
    proc = subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.fail(f"{' '.join(args[:2])} exited {proc.returncode}:\n{proc.stdout}{proc.stderr}", pytrace=False)


def test_ruff_check():
    _run("ruff", "check", "--no-fix", ".")


def test_ruff_format():
    _run("ruff", "format", "--check", ".")


@pytest.mark.slow
def test_mypy():
    _run("mypy", "-p", "avq")
