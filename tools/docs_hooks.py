"""MkDocs hook of the user guide (``hooks:`` in ``mkdocs.yml``): a page line ``<!-- generated: NAME -->`` is
replaced by the markdown that ``tools/docs_tables.py`` builds from the code (``tasks``, ``robot``, ``cli``,
``recipes``), so the
reference tables are never typed by hand. Each table is built once per build.
"""

from __future__ import annotations

import functools
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tools/ is no package: docs_tables sits beside this file

import docs_tables  # noqa: E402

MARKER = re.compile(r"^<!-- generated: ([a-z_]+) -->$", re.M)
GENERATORS = {"tasks": docs_tables.tasks_page, "robot": docs_tables.robot_page, "cli": docs_tables.cli_page,
              "recipes": docs_tables.recipes_page}


@functools.cache
def generated(name: str) -> str:
    """The markdown of generator ``name`` (built once)."""
    if name not in GENERATORS:
        raise ValueError(f"unknown generated table {name!r}; known: {sorted(GENERATORS)}")
    return GENERATORS[name]()


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001  (MkDocs hook signature)
    """Replace each ``<!-- generated: NAME -->`` line of a page by its table."""
    return MARKER.sub(lambda m: generated(m.group(1)), markdown)
