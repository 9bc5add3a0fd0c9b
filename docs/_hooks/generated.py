"""MkDocs hook: the reference pages that are generated from the code, not written by hand.

A page asks for a generated section with an HTML comment on a line of its own:

- ``<!-- avq:cli -->``: every command of ``avq`` with its ``--help``, from the parser ``avq.cli.build_parser()``;
- ``<!-- avq:agents -->``: every agent name with its class, what it is, and its defaults, read from the
  data files ``src/avq/agents/defaults/<name>.yaml`` through ``avq.agents.registry`` (``ENTRIES``: name ->
  {environment id or ``"*"`` -> the entry's class, parameters, reason and link}, and ``SUMMARIES``).

So these pages cannot drift from the code: change the parser or the table and the site follows.
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path
from typing import Any

MARKERS = ("<!-- avq:cli -->", "<!-- avq:agents -->", "<!-- avq:layout -->")


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return text.replace("|", r"\|").replace("\n", " ")


def cli_reference() -> str:
    """Markdown for every command of ``avq``: what it does and its help, as ``avq COMMAND --help`` prints it."""
    from avq.cli import build_parser

    parser = build_parser()
    parts = [f"```text\n{parser.format_help().strip()}\n```"]
    for name, (sub, summary) in parser.commands.items():
        parts += [
            f"## `avq {name}` {{#avq-{name}}}",
            f"{summary[:1].upper() + summary[1:]}.",
            f"```text\n{sub.format_help().strip()}\n```",
        ]
    return "\n\n".join(parts) + "\n"


def _value(value: Any) -> str:
    return f"`{value!r}`"


def agents_reference() -> str:
    """Markdown for every agent name: class, summary, and a table of defaults, one column per entry, with each
    entry's reason and the link to the measurements that chose it."""
    from avq.agents.registry import ENTRIES, SUMMARIES

    overview = ["| name | class | per-environment entries |", "|---|---|---|"]
    sections = []
    for name, entries in ENTRIES.items():
        main = entries["*"].cls.__name__
        others = [key for key in entries if key != "*"]
        overview.append(
            f"| [`{name}`](#{name}) | [`{main}`][avq.agents.{main}] | "
            + (", ".join(f"`{key}`" for key in others) or "-")
            + " |"
        )
        signatures = {key: inspect.signature(e.cls.__init__).parameters for key, e in entries.items()}
        params = list(dict.fromkeys(p for e in entries.values() for p in e.params))
        head = ['everywhere (`"*"`)' if key == "*" else f"`{key}`" for key in entries]
        rows = [f"| parameter | {' | '.join(head)} |", "|---|" + "---|" * len(entries)]
        for param in params:
            cells = []
            for key, e in entries.items():
                if param in e.params:
                    cells.append(_value(e.params[param]))
                elif param in signatures[key]:
                    cells.append(_value(signatures[key][param].default) + " *(class)*")
                else:
                    cells.append("-")
            rows.append(f"| `{param}` | " + " | ".join(cells) + " |")
        classes = {key: e.cls for key, e in entries.items()}
        if len(set(classes.values())) == 1:
            which = f"Class: [`{main}`][avq.agents.{main}]."
        else:
            which = (
                "Class: "
                + "; ".join(
                    f"[`{cls.__name__}`][avq.agents.{cls.__name__}] "
                    + ("everywhere else" if key == "*" else f"on `{key}`")
                    for key, cls in sorted(classes.items(), key=lambda kv: kv[0] == "*")
                )
                + "."
            )
        why = "\n".join(
            f"- {'everywhere' if key == '*' else f'`{key}`'}: {_cell(e.reason)} ([why](../{e.results}))"
            for key, e in entries.items()
        )
        sections.append(
            f"## `{name}` {{#{name}}}\n\n{SUMMARIES.get(name, '')}\n\n{which} "
            f"Data file: `src/avq/agents/defaults/{name}.yaml`.\n\n{why}\n\n" + "\n".join(rows)
        )
    return "\n".join(overview) + "\n\n" + "\n\n".join(sections) + "\n"


def _package_root() -> Path:
    import avq

    return Path(avq.__file__).parent


def _first_line(path: Path) -> str:
    """The first sentence of a module's docstring (a package: of its ``__init__.py``)."""
    source = (path / "__init__.py" if path.is_dir() else path).read_text(encoding="utf-8")
    doc = ast.get_docstring(ast.parse(source)) or ""
    first = " ".join(doc.split("\n\n")[0].split()).replace("``", "")
    first = first.split(". ")[0].rstrip(".")
    return first if len(first) <= 64 else first[:63].rstrip() + "…"


def _room(module: str) -> str:
    """The room of a module: ``avq.agents.plan.model`` -> ``agents/plan``, ``avq.rules`` -> ``rules``."""
    parts = module.split(".")[1:]
    if parts[:1] == ["agents"] and len(parts) > 2:
        return "/".join(parts[:2])
    return parts[0] if parts else "avq"


def _imports(root: Path) -> dict[str, set[str]]:
    """room -> the rooms it imports (module-level imports of ``avq`` modules only)."""
    edges: dict[str, set[str]] = {}
    for path in sorted(root.rglob("*.py")):
        module = ("avq." + ".".join(path.relative_to(root).with_suffix("").parts)).removesuffix(".__init__")
        room = _room(module)
        if room == "avq":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            names = (
                [node.module]
                if isinstance(node, ast.ImportFrom) and node.module
                else [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else []
            )
            for name in names:
                if name.startswith("avq.") and _room(name) not in (room, "avq"):
                    edges.setdefault(room, set()).add(_room(name))
    return edges


def layout_reference() -> str:
    """The package's layout, read from the code: every folder and module with its line count and the first
    sentence of its docstring, and which room imports which."""
    root = _package_root()
    lines = ["```text"]
    for path in sorted(root.rglob("*"), key=lambda p: p.relative_to(root).parts):
        rel = path.relative_to(root)
        if "__pycache__" in rel.parts or path.name == "__init__.py" or not (path.is_dir() or path.suffix == ".py"):
            continue
        if path.is_dir() and not (path / "__init__.py").exists():
            continue
        depth = len(rel.parts) - 1
        name = path.name + ("/" if path.is_dir() else "")
        size = "" if path.is_dir() else f"{len(path.read_text(encoding='utf-8').splitlines()):4d}"
        lines.append(f"{'    ' * depth}{name:<{28 - 4 * depth}} {size:>4}  {_first_line(path)}")
    lines.append("```")
    edges = _imports(root)
    table = ["| room | imports |", "|---|---|"]
    for room in sorted(edges):
        table.append(f"| `{room}` | " + ", ".join(f"`{r}`" for r in sorted(edges[room])) + " |")
    return (
        "\n".join(lines)
        + "\n\nWho imports whom (a room is a top-level module, or a folder of the agents):\n\n"
        + "\n".join(table)
        + "\n"
    )


GENERATORS = {
    "<!-- avq:cli -->": cli_reference,
    "<!-- avq:agents -->": agents_reference,
    "<!-- avq:layout -->": layout_reference,
}


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    for marker, generate in GENERATORS.items():
        if marker in markdown:
            markdown = markdown.replace(marker, generate())
    return markdown
