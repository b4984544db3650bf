"""The tutorial's second and third chapters run as written: each page is followed in a scratch copy of the
repository, from its root, at the sizes it writes (training cut to 2 steps, a policy's rollouts to 40), and every
output it shows is compared with what its command printed, within the tolerance the page states
(``tools/docs_snippets.py``). A command the page shows being refused must be refused. The first chapter, which
also writes a task, has its own file (``tests/test_tutorial_simple_task.py``)."""

from __future__ import annotations

import re
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
    assert result["failed"] is None, (
        f"{result['failed']}: {result['error']}\n{result['trace']}\n{result.get('log', '')[-3000:]}"
    )
    assert result["outputs_compared"] == len(docs_snippets.outputs(page)) > 0
    assert result["stray"] == [], f"the page's commands left files outside outputs/: {result['stray']}"


def test_the_component_chapter_writes_a_task_of_its_own():
    """Chapter 2 writes ``tasks/my_place/`` (its plan, its package, the scenario the reader saved): a new id, named
    on the page, in a folder that is not in the working tree."""
    from newton_lab.task_api.catalog import declared_task_ids

    page = CHAPTERS[0]
    written = {s.writes: s.code for s in docs_snippets.snippets(page) if s.writes}
    assert set(written) == {"tasks/my_place/__init__.py", "tasks/my_place/config/g1/place_plan.yaml"}
    assert "cp outputs/pts/nav_end.yaml tasks/my_place/config/g1/start.yaml" in page.read_text()
    ids = re.findall(r'\bid="([^"]+)"', written["tasks/my_place/__init__.py"])
    assert ids == ["GalbotG1-MyPlace-v0"] and f"`{ids[0]}`" in page.read_text()
    assert not set(ids) & set(declared_task_ids())
    assert not (ROOT / "tasks" / "my_place").exists(), "tasks/my_place is in the working tree: the chapter writes it"
