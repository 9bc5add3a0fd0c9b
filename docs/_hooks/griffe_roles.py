"""Griffe extension: the cross-references of avq's docstrings, as mkdocstrings links.

avq's docstrings are Google style and name other objects in two ways: reST roles
(``:func:`make_agent```, ``:class:`avq.sweep.SweepConfig```) and ``avq.``-qualified names in
backticks (`avq.agents.BaseAgent.save`). Both become autorefs links (``[`make_agent`][avq.agents.registry.make_agent]``)
when the name is found: as written, or relative to the documented object and its parents (its class,
its module, its package). A role naming something outside avq (``gymnasium.make``) stays code.
With ``mkdocs build --strict``, a link whose target is not on any page fails the build.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r"(?::py)?:(?:mod|func|data|const|class|meth|attr|exc|obj):`~?([^`]+)`")
QUALIFIED = re.compile(r"(?<![`\[\w])`(avq(?:\.[A-Za-z_]\w*)+)(\(\))?`(?!\])")


class DocstringRoles(griffe.Extension):
    """Rewrite every docstring of the package once it is loaded.

    Args:
        documented: The modules that have a page in the reference. A name found in another module (a
            private one, say) stays code rather than a link to a page that does not exist.
    """

    def __init__(self, documented: list[str] | None = None) -> None:
        super().__init__()
        self.documented = tuple(documented or ())

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        if pkg.name != "avq":
            return
        collection = pkg.modules_collection
        for obj in _walk(pkg):
            if obj.is_attribute and not obj.docstring:
                _comment_docstring(obj)
        for obj in _walk(pkg):
            if obj.docstring:
                obj.docstring.value = _rewrite(obj.docstring.value, obj, collection, self.documented)


def _walk(obj: griffe.Object):
    yield obj
    for member in obj.members.values():
        if not member.is_alias:
            yield from _walk(member)


def _comment_docstring(attr: griffe.Object) -> None:
    """An attribute documented by ``#:`` comment lines just above it gets them as its docstring."""
    try:
        lines = attr.module.lines
    except (AttributeError, OSError):
        return
    if not attr.lineno or not lines:
        return
    comment, k = [], attr.lineno - 2  # the line above the assignment, 0-based
    while k >= 0 and lines[k].strip().startswith("#:"):
        comment.insert(0, lines[k].strip()[2:].strip())
        k -= 1
    if comment:
        attr.docstring = griffe.Docstring("\n".join(comment), lineno=attr.lineno, parent=attr)


def _exists(path: str, collection: Any, documented: tuple[str, ...] = ()) -> bool:
    """Whether ``path`` names an object that the reference shows: it has a docstring (or is a module),
    and it is in one of the ``documented`` modules (by the path it is named with, or where it is defined)."""
    try:
        obj = collection[path]
    except (KeyError, ValueError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return False
    try:
        if not (obj.is_module or obj.docstring):
            return False
        if not documented:
            return True
        if (obj.path if obj.is_module else obj.module.path) in documented:
            return True
        # named through a documented module (``avq.agents.BaseAgent.save``): that module's page shows it,
        # unless the name goes on into a module that has no page
        prefixes = [m for m in documented if path.startswith(m + ".")]
        if not prefixes:
            return False
        head = max(prefixes, key=len)
        first = collection[f"{head}.{path[len(head) + 1 :].split('.')[0]}"]
        return not (first.is_module and first.path not in documented)
    except (griffe.AliasResolutionError, griffe.CyclicAliasError):
        return False


def _resolve(name: str, obj: griffe.Object, collection: Any, documented: tuple[str, ...]) -> str | None:
    name = name.removesuffix("()")
    if name.startswith("avq."):
        return name if _exists(name, collection, documented) else None
    scope: griffe.Object | None = obj
    while scope is not None:
        candidate = f"{scope.path}.{name}"
        if _exists(candidate, collection, documented):
            return candidate
        scope = scope.parent
    return None


def _rewrite(text: str, obj: griffe.Object, collection: Any, documented: tuple[str, ...]) -> str:
    def role(match: re.Match) -> str:
        name = match.group(1)
        target = _resolve(name, obj, collection, documented)
        return f"[`{name}`][{target}]" if target else f"`{name}`"

    def qualified(match: re.Match) -> str:
        target = _resolve(match.group(1), obj, collection, documented)
        return f"[`{match.group(1)}{match.group(2) or ''}`][{target}]" if target else match.group(0)

    return QUALIFIED.sub(qualified, ROLE.sub(role, text))
