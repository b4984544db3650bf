"""MkDocs hook of the user guide (``hooks:`` in ``mkdocs.yml``): a page line ``<!-- generated: NAME -->`` is
replaced by the markdown that ``tools/docs_tables.py`` builds from the code (``tasks``, ``robot``, ``cli``,
``recipes``, ``perturbations``), so the reference tables are never typed by hand. Each table is built once per
build. An inline ``<!-- figure: NAME -->`` (``demo_cpu``, ``demo_gpu``, ``picktoshelf_cpu``, ...) is replaced by a
figure read from the newest run record in ``docs/results/``, linked to it (``docs_tables.FIGURES``): time promises
are the records', never typed.
"""

from __future__ import annotations

import functools
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tools/ is no package: docs_tables sits beside this file

import docs_tables  # noqa: E402

MARKER = re.compile(r"^<!-- generated: ([a-z_]+) -->$", re.M)
FIGURE = re.compile(r"(?<!`)<!-- figure: ([a-z_]+) -->(?!`)")
"""An inline figure marker; one in backticks is a page showing the marker itself (Contributing), left as it is."""
GENERATORS = {
    "tasks": docs_tables.tasks_page,
    "robot": docs_tables.robot_page,
    "cli": docs_tables.cli_page,
    "recipes": docs_tables.recipes_page,
    "perturbations": docs_tables.perturbations_page,
}


@functools.cache
def generated(name: str) -> str:
    """The markdown of generator ``name`` (built once)."""
    if name not in GENERATORS:
        raise ValueError(f"unknown generated table {name!r}; known: {sorted(GENERATORS)}")
    return GENERATORS[name]()


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001  (MkDocs hook signature)
    """Replace each ``<!-- generated: NAME -->`` line of a page by its table, each ``<!-- figure: NAME -->`` by
    its figure."""
    markdown = MARKER.sub(lambda m: generated(m.group(1)), markdown)
    return FIGURE.sub(lambda m: figure(m.group(1), page.file.src_uri), markdown)


def figure(name: str, page: str) -> str:
    """The text of inline figure ``name`` on the page ``page`` (its path under ``docs/``)."""
    if name not in docs_tables.FIGURES:
        raise ValueError(f"unknown figure {name!r} on {page}; known: {sorted(docs_tables.FIGURES)}")
    return docs_tables.FIGURES[name](page)
