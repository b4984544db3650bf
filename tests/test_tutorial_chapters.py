"""The tutorial's second and third chapters run as written: each page is followed in a scratch copy of the
repository, from its root, at the sizes it writes (training cut to 2 steps, a policy's rollouts to 40), and every
output it shows is compared with what its command printed, within the tolerance the page states
(``tools/docs_snippets.py``). A command the page shows being refused must be refused. The first chapter, which
also writes a task, has its own file (``tests/test_tutorial_simple_task.py``)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))  # tools/ is no package

import docs_snippets  # noqa: E402

CHAPTERS = [ROOT / "docs" / "tutorial" / "component_tasks.md", ROOT / "docs" / "tutorial" / "compound_task.md"]


@pytest.mark.parametrize("page", CHAPTERS, ids=lambda p: p.stem)
def test_every_shown_output_is_marked_and_follows_a_command(page):
    assert docs_snippets.in_copy(page)
    assert docs_snippets.check_outputs(page) == []
    text = page.read_text()
    shown = text.count("```text")
    marked = len(docs_snippets.outputs(page))
    assert marked == shown, f"{page.name}: {shown} text blocks, {marked} of them compared outputs"


@pytest.mark.slow
@pytest.mark.parametrize("page", CHAPTERS, ids=lambda p: p.stem)
def test_the_chapter_runs_as_written_and_prints_what_it_shows(page, tmp_path):
    result = docs_snippets.run_in_copy(page, tmp_path / "repo")
    assert result["failed"] is None, \
        f"{result['failed']}: {result['error']}\n{result['trace']}\n{result.get('log', '')[-3000:]}"
    assert result["outputs_compared"] == len(docs_snippets.outputs(page)) > 0
    assert result["stray"] == [], f"the page's commands left files outside outputs/: {result['stray']}"
