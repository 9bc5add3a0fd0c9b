"""The README's examples run: every ```python block executes, and every ``avq.`` name it quotes exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import avq

README = Path(__file__).resolve().parents[1] / "README.md"
TEXT = README.read_text(encoding="utf-8")
#: The README's ```python blocks, with the line each starts on.
BLOCKS = [
    (TEXT.count("\n", 0, m.start()) + 2, m.group(1)) for m in re.finditer(r"^```python\n(.*?)^```", TEXT, re.M | re.S)
]
#: Every dotted ``avq.`` name in the README's inline code and code blocks, without call arguments.
NAMES = sorted(set(re.findall(r"(?<![\w./-])avq(?:\.[A-Za-z_]\w*)+", TEXT)))


def test_the_readme_has_python_examples_and_names_avq_objects():
    assert BLOCKS and "avq.checks.check_agent" in NAMES and "avq.make_agent" in NAMES


@pytest.mark.parametrize(("line", "code"), BLOCKS, ids=[f"README.md:{line}" for line, _ in BLOCKS])
def test_python_block_runs(line, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the examples write files (agent.save("maze-agent.zip"))
    exec(compile(code, f"README.md:{line}", "exec"), {"__name__": "__readme__"})


@pytest.mark.parametrize("name", NAMES)
def test_name_exists_after_import_avq(name):
    obj = avq
    for part in name.split(".")[1:]:
        assert hasattr(obj, part), f"README.md names {name}, but after `import avq` {obj.__name__} has no {part!r}"
        obj = getattr(obj, part)
