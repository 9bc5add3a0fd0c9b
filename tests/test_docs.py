"""The documentation site builds, its generated pages follow the code, and its tutorial runs.

- ``mkdocs build --strict`` succeeds: every link and anchor between pages resolves, and every
  cross-reference a docstring makes to avq's API is found (the griffe extension of ``docs/_hooks``
  turns them into links, and a link to nothing fails a strict build);
- the agent-defaults page shows every entry of ``avq.agents.registry.DEFAULTS`` and the command-line
  page every command and option of ``avq.cli.build_parser()``;
- every public name has a docstring, and no private module has a page;
- every ```python block of the tutorial runs, in order, in one namespace (the README's: tests/test_readme.py);
- the how-to on a user's own task runs as a reader follows it: its module written to a file, its ``avq``
  commands in new processes, its Python blocks in order.
"""

from __future__ import annotations

import html
import importlib
import inspect
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import gymnasium
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
TUTORIAL = DOCS / "tutorial" / "index.md"
HOW_TO_OWN_TASK = DOCS / "how-to" / "own-task.md"
#: The modules of the API reference: their ``__all__`` is the public API.
PUBLIC_MODULES = (
    "avq",
    "avq.agents",
    "avq.agents.callbacks",
    "avq.agents.registry",
    "avq.agents.save_util",
    "avq.envs",
    "avq.evaluation",
    "avq.checks",
    "avq.sweep",
    "avq.plotting",
)


def python_blocks(path: Path) -> list[tuple[int, str]]:
    """The ```python blocks of a Markdown file, with the line each starts on."""
    text = path.read_text(encoding="utf-8")
    return [
        (text.count("\n", 0, m.start()) + 2, m.group(1))
        for m in re.finditer(r"^```python\n(.*?)^```", text, re.M | re.S)
    ]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built in strict mode into a temporary directory."""
    pytest.importorskip("mkdocs")
    out = tmp_path_factory.mktemp("site")
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
        "NO_MKDOCS_2_WARNING": "1",
    }
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"), "-d", str(out)],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
    )
    assert result.returncode == 0, result.stderr[-5000:]
    return out


def _text(page: Path) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", page.read_text(encoding="utf-8")))


def test_the_site_builds_strict_with_its_sections(site):
    for page in (
        "index.html",
        "tutorial/index.html",
        "reference/agents.html",
        "reference/cli.html",
        "reference/file-formats.html",
        "reference/api/avq.html",
        "reference/api/agents.html",
        "explanation/paper.html",
        "explanation/architecture.html",
        "results/index.html",
    ):
        assert (site / page).is_file(), page
    assert len(list((site / "results").glob("*.html"))) >= 5


def test_the_api_reference_has_the_public_classes_and_no_private_module(site):
    agents = (site / "reference" / "api" / "agents.html").read_text(encoding="utf-8")
    import avq.agents
    import avq.agents.callbacks

    callbacks = (site / "reference" / "api" / "callbacks.html").read_text(encoding="utf-8")
    for name in avq.agents.__all__:
        if inspect.isclass(getattr(avq.agents, name)):
            if getattr(avq.agents, name).__module__ == "avq.agents.callbacks":
                assert f'id="avq.agents.callbacks.{name}"' in callbacks, name
            else:
                assert f'id="avq.agents.{name}"' in agents, name
    names = {p.name for p in (site / "reference" / "api").glob("*.html")}
    assert not any(n.startswith("_") for n in names)


def test_the_defaults_page_shows_every_entry_of_the_registry(site):
    from avq.agents.registry import DEFAULTS, ENTRIES

    page = (site / "reference" / "agents.html").read_text(encoding="utf-8")
    for name, table in DEFAULTS.items():
        start = page.index(f'id="{name}"')
        end = min(
            [page.index(f'id="{other}"') for other in DEFAULTS if other != name and page.index(f'id="{other}"') > start]
            or [len(page)]
        )
        section = page[start:end]
        assert all(
            e.cls.__name__ in section and e.reason.split(":")[0] in html.unescape(section)
            for e in ENTRIES[name].values()
        ), name
        rows = {}
        for row in re.findall(r"<tr>(.*?)</tr>", section, re.S):
            cells = [html.unescape(re.sub(r"<[^>]+>", "", c)).strip() for c in re.findall(r"<td>(.*?)</td>", row, re.S)]
            if cells:
                rows[cells[0]] = cells[1:]
        for column, entry in enumerate(table.values()):
            for param, value in entry.items():
                assert rows[param][column] == repr(value), (name, param)


def test_the_cli_page_shows_every_command_and_option(site):
    from avq.cli import build_parser

    text = _text(site / "reference" / "cli.html")
    parser = build_parser()
    assert set(parser.commands) == {"reproduce", "train", "sweep", "evaluate", "tune", "plot"}
    for command, (sub, _) in parser.commands.items():
        assert f"avq {command}" in text, command
        flags = set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", sub.format_help()))
        assert {"--out", "--help"} & flags, command
        for flag in flags:
            assert flag in text, (command, flag)


@pytest.mark.parametrize("module", PUBLIC_MODULES)
def test_every_public_name_has_a_docstring(module):
    mod = importlib.import_module(module)
    assert inspect.getdoc(mod), module
    for name in getattr(mod, "__all__", []):
        obj = getattr(mod, name)
        if inspect.isclass(obj) or inspect.isfunction(obj) or inspect.ismodule(obj):
            assert inspect.getdoc(obj), f"{module}.{name} has no docstring"


def test_the_hand_written_pages_speak_of_the_project_only():
    for page in DOCS.rglob("*.md"):
        text = page.read_text(encoding="utf-8")
        assert not re.search(r"\bSPEC\b|the issue", text), page


def test_the_tutorial_runs(tmp_path, monkeypatch):
    """Every block of the tutorial, in order, in one namespace (as a reader runs them)."""
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)  # the tutorial writes figures and a model file
    blocks = python_blocks(TUTORIAL)
    assert len(blocks) >= 4
    namespace = {"__name__": "__tutorial__"}
    for line, code in blocks:
        exec(compile(code, f"{TUTORIAL.relative_to(ROOT)}:{line}", "exec"), namespace)
    assert (tmp_path / "partition.png").stat().st_size > 0 and (tmp_path / "maze-agent.zip").is_file()


def test_the_own_task_how_to_runs(tmp_path, monkeypatch):
    """The how-to on a user's own task, as a reader follows it in a new directory: a ```python block that
    starts with ``# NAME.py`` is saved as that file, every ``avq`` line of a ```bash block runs in a new
    process there, and the other ```python blocks run in order, in one namespace, as a script of that
    directory (which Python puts on the path)."""
    import matplotlib

    from conftest import cli_subprocess

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    text = HOW_TO_OWN_TASK.read_text(encoding="utf-8")
    namespace = {"__name__": "__how_to__"}
    ran = []
    try:
        for m in re.finditer(r"^```(python|bash)\n(.*?)^```", text, re.M | re.S):
            where = f"{HOW_TO_OWN_TASK.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 2}"
            kind, code = m.groups()
            file = re.match(r"# (\w+\.py)\b", code)
            if kind == "python" and file:
                (tmp_path / file.group(1)).write_text(code, encoding="utf-8")
            elif kind == "python":
                exec(compile(code, where, "exec"), namespace)
            else:
                for command in (shlex.split(line, comments=True) for line in code.splitlines()):
                    if command[:1] == ["avq"]:
                        result = cli_subprocess(*command[1:], cwd=tmp_path)
                        assert result.returncode == 0, (where, command, result.stderr)
                        ran.append(command[1])
    finally:
        sys.modules.pop("nav3d", None)
        gymnasium.registry.pop("user/Nav3D-v0", None)
    assert ran.count("train") >= 3 and ran.count("evaluate") >= 3 and ran.count("tune") >= 2
    assert (tmp_path / "nav3d-curve.png").stat().st_size > 0 and (tmp_path / "nav3d-agent.zip").is_file()
    assert (tmp_path / "nav3d-agent_policy_0-1.png").stat().st_size > 0  # (the saved file, opened by avq plot)
    assert (tmp_path / "runs/nav3d/policy_0-1.png").stat().st_size > 0 and (tmp_path / "study.db").is_file()
    tuned = yaml.safe_load((tmp_path / "runs/nav3d-tuned/config.yml").read_text(encoding="utf-8"))
    assert (tuned["env"], tuned["episodes"]) == ("nav3d:user/Nav3D-v0", 300)
