"""The linters pass: ``ruff check`` and ``ruff format --check`` on the repository, ``mypy`` on the whole package.

Their settings are in pyproject.toml; the tools come with the ``test`` extra, so the README's test
command (``pip install ".[test]" && pytest``, all that CI runs) runs them too.
"""

from __future__ import annotations

import ast
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


#: The house's limits (docs/explanation/architecture.md): a module a reader takes in at one sitting, and a compiled
#: function that takes a few typed records rather than dozens of arrays.
MAX_MODULE_LINES, MAX_COMPILED_PARAMS = 450, 12


def test_modules_and_compiled_functions_stay_within_the_house_limits():
    long, wide = [], []
    for path in sorted((ROOT / "src").rglob("*.py")):
        text = path.read_text()
        if text.count("\n") > MAX_MODULE_LINES:
            long.append((path.relative_to(ROOT).as_posix(), text.count("\n")))
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef) and any("njit" in ast.unparse(d) for d in node.decorator_list):
                n = len(node.args.posonlyargs) + len(node.args.args) + len(node.args.kwonlyargs)
                if n > MAX_COMPILED_PARAMS:
                    wide.append((path.relative_to(ROOT).as_posix(), node.name, n))
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"
    assert not wide, f"compiled functions with more than {MAX_COMPILED_PARAMS} parameters: {wide}"
