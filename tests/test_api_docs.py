"""The API reference (``python docs/build_api.py``, pdoc) builds, has a section per agent name with the
registry's defaults, and every reference in it resolves: links to pages and anchors that exist, and every
cross-reference written in a docstring (``avq.``-qualified names in backticks, reST roles such as
``:func:`make_agent```) turned into a link."""

from __future__ import annotations

import html
import importlib.util
import re
import runpy
import subprocess
import sys
from collections import defaultdict
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urlsplit

import pdoc.doc
import pytest

from avq.agents.registry import CLASSES, DEFAULTS

BUILD = Path(__file__).resolve().parents[1] / "docs" / "build_api.py"
#: An ``avq.``-qualified name in a code span, which pdoc links when it names a documented object.
QUALIFIED = re.compile(r"avq(\.[A-Za-z_]\w*)+(\(\))?")
#: A reST cross-reference role, as pdoc converts it (``:func:`f``` -> ``f()``, others -> the name).
ROLE = re.compile(r"(?::py)?:(mod|func|data|const|class|meth|attr|exc|obj):`([^`]+)`")
_VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}


class _Page(HTMLParser):
    """One HTML page: its ids, its links, and every code span of its docstrings with the innermost element id
    around it (the documented object's qualname) and whether it is a link."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.hrefs: list[str] = []
        self.codes: list[tuple[str, str, bool]] = []  # (owner id, text, linked)
        self._stack: list[tuple[str, str | None, bool, bool, bool]] = []  # tag, id, docstring, link, pre
        self._text: list[str] | None = None
        self._linked = False

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("href"):
            self.hrefs.append(attrs["href"])
        if tag in _VOID:
            return
        _, _, doc, link, pre = self._stack[-1] if self._stack else ("", None, False, False, False)
        self._stack.append((tag, attrs.get("id"), doc or "docstring" in (attrs.get("class") or "").split(),
                            link or tag == "a", pre or tag == "pre"))
        if tag == "code" and doc and not pre:
            self._text, self._linked = [], link  # a link around the code span, or (below) inside it
        elif tag == "a" and self._text is not None:
            self._linked = True

    def handle_endtag(self, tag):
        if tag in _VOID or not self._stack:
            return
        while self._stack:
            open_tag, *_ = self._stack.pop()
            if open_tag == tag:
                break
        if tag == "code" and self._text is not None:
            owner = next((i for _, i, *_ in reversed(self._stack) if i), "")
            self.codes.append((owner, "".join(self._text), self._linked))
            self._text = None

    def handle_data(self, data):
        if self._text is not None:
            self._text.append(data)


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def _documented(module: pdoc.doc.Module):
    """Every object of a module's page, module first: (its element id, its docstring)."""
    yield "", module.docstring
    todo = list(module.members.values())
    while todo:
        doc = todo.pop()
        yield doc.qualname, doc.docstring
        if isinstance(doc, pdoc.doc.Class):
            todo.extend(doc.own_members)


def broken_references(root: Path) -> list[str]:
    """What does not resolve in the reference under ``root``: one line per problem."""
    pages = {path: _parse(path) for path in sorted(root.rglob("*.html"))}
    problems = []
    for path, page in pages.items():
        where = path.relative_to(root)
        for href in page.hrefs:
            parts = urlsplit(href)
            if parts.scheme or parts.netloc or href.startswith(("mailto:", "javascript:")):
                continue
            target = (path.parent / parts.path).resolve() if parts.path else path
            if target not in pages:
                problems.append(f"{where}: link {href!r} to a page that does not exist")
            elif parts.fragment and html.unescape(parts.fragment) not in pages[target].ids:
                problems.append(f"{where}: link {href!r} to an anchor that does not exist")
        for owner, text, linked in page.codes:
            if not linked and QUALIFIED.fullmatch(text):
                problems.append(f"{where}: `{text}` (in {owner or 'the module docstring'}) names nothing documented")
        if path.name == "index.html" and path.parent == root:
            continue
        modname = ".".join(where.with_suffix("").parts)
        by_owner = defaultdict(list)
        for owner, text, linked in page.codes:
            by_owner[owner].append((text, linked))
        for owner, docstring in _documented(pdoc.doc.Module.from_name(modname)):
            if owner and owner not in page.ids:
                continue  # not shown on this page (private)
            for kind, name in ROLE.findall(docstring):
                if name.partition(".")[0] not in ("avq", name) and importlib.util.find_spec(name.partition(".")[0]):
                    continue  # another library's object (gymnasium.make): pdoc links only what it documents
                text = f"{name}()" if kind in ("func", "meth") else name
                if not any(linked for t, linked in by_owner[owner] if t == text):
                    problems.append(f"{where}: :{kind}:`{name}` (in {owner or 'the module docstring'}) does not resolve")
    return problems


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The reference, built by the README's command into a temporary directory."""
    out = tmp_path_factory.mktemp("api")
    result = subprocess.run([sys.executable, str(BUILD), "--out", str(out)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "Warning" not in result.stderr, result.stderr  # (pdoc warns of what it cannot read)
    return out


def test_the_public_api_has_its_pages(reference):
    pages = {str(p.relative_to(reference)) for p in reference.rglob("*.html")}
    assert {"avq.html", "avq/agents.html", "avq/agents/registry.html", "avq/envs.html", "avq/checks.html"} <= pages
    assert not any("/_" in p or p.startswith("_") for p in pages)  # private modules stay out
    assert 'id="AVQSarsa"' in (reference / "avq" / "agents.html").read_text()


def test_each_agent_name_has_a_section_with_the_registry_defaults(reference):
    text = (reference / "avq" / "agents" / "registry.html").read_text(encoding="utf-8")
    for name, table in DEFAULTS.items():
        start = text.index(f'<h3 id="{name}">')
        section = text[start:text.find("<h3 ", start + 1)]
        assert f"avq.agents.{CLASSES[name].__name__}</a>" in section, name
        rows = {}
        for row in re.findall(r"<tr>(.*?)</tr>", section, re.S):
            cells = [html.unescape(re.sub(r"<[^>]+>", "", c)).strip() for c in re.findall(r"<td>(.*?)</td>", row, re.S)]
            if cells:  # (the head row has <th> cells)
                rows[cells[0]] = cells[1:]
        for column, entry in enumerate(table.values()):
            for param, value in entry.items():
                assert rows[param][column] == repr(value), (name, param)


def test_every_reference_resolves(reference):
    assert broken_references(reference) == []


def test_a_broken_reference_is_found(tmp_path):
    module = tmp_path / "refs_demo.py"
    module.write_text('''"""Uses `avq.NoSuchThing` and :func:`missing`, :func:`present`, `avq.AVQSarsa` and [a page](nowhere.html)."""


def present():
    """Here; see :class:`Absent` and :meth:`present`."""
''')
    runpy.run_path(str(BUILD))["build"](tmp_path / "html", modules=(str(module),))
    sys.modules.pop("refs_demo", None)
    assert sorted(broken_references(tmp_path / "html")) == sorted([
        "refs_demo.html: link 'nowhere.html' to a page that does not exist",
        "refs_demo.html: `avq.NoSuchThing` (in the module docstring) names nothing documented",
        "refs_demo.html: `avq.AVQSarsa` (in the module docstring) names nothing documented",
        "refs_demo.html: :func:`missing` (in the module docstring) does not resolve",
        "refs_demo.html: :class:`Absent` (in present) does not resolve",
    ])
