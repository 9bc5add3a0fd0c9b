"""Build avq's API reference, HTML from the docstrings, with pdoc.

    pip install ".[docs]" && python docs/build_api.py      # writes docs/api/index.html

The reference covers the public API as each package's ``__all__`` declares it: ``avq`` and its
public subpackages and modules (``avq.agents``, ``avq.agents.registry``, with a section per agent
name and its defaults read from ``DEFAULTS``, ``avq.agents.save_util``, ``avq.envs``,
``avq.checks``, ``avq.sweep``). Docstrings are Google style. ``tests/test_api_docs.py`` builds it
and fails on a reference that does not resolve.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pdoc
import pdoc.render

import avq

#: The packages documented; pdoc follows each package's ``__all__`` to its public submodules.
MODULES = ("avq",)
#: Where the reference goes by default (ignored by git).
DEFAULT_OUT = Path(__file__).resolve().parent / "api"


def build(out: Path, modules: tuple[str, ...] = MODULES) -> list[Path]:
    """Write the reference of ``modules`` (names or paths, as pdoc takes them) into ``out``; return its HTML pages."""
    pdoc.render.configure(docformat="google", footer_text=f"avq {avq.__version__}", search=True, show_source=True)
    pdoc.pdoc(*modules, output_directory=Path(out))
    return sorted(Path(out).rglob("*.html"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Build avq's API reference (HTML) with pdoc.")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    args = parser.parse_args(argv)
    pages = build(args.out)
    print(f"wrote {len(pages)} pages; open {args.out / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
