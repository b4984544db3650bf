"""The tutorial's first chapter builds a task from an empty folder: a reader who follows
``docs/tutorial/simple_task.md`` in a fresh copy of the repository writes ``tasks/my_push/``, and every block of
the page runs as written (training cut to 2 steps, the policy's rollouts to 40), in order, from the copy's root.
Every output the page shows is compared with what its command printed, within the tolerance the page states
(``tools/docs_snippets.py``). The page names every id the new package registers and says they must be unique;
none of them is taken; the commands write nowhere but ``outputs/`` and the new task folder."""

from __future__ import annotations

import re
import shlex
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))  # tools/ is no package

import docs_snippets  # noqa: E402

PAGE = ROOT / "docs" / "tutorial" / "simple_task.md"
TASK_DIR = "tasks/my_push"
PATH_FLAGS = ("--out", "--dataset-path", "--output-path", "--output-dir", "--rerun-save", "--checkpoint")


def _written() -> dict[str, str]:
    return {s.writes: s.code for s in docs_snippets.snippets(PAGE) if s.writes}


def _ids(source: str) -> list[str]:
    return re.findall(r'\bid="([^"]+)"', source)


def test_the_page_writes_a_whole_task_package_from_nothing():
    written = _written()
    assert set(written) == {
        f"{TASK_DIR}/__init__.py",
        f"{TASK_DIR}/scene.py",
        f"{TASK_DIR}/config/g1/env_cfg.py",
        f"{TASK_DIR}/config/g1/motion_plan.yaml",
    }
    assert not (ROOT / TASK_DIR).exists(), f"{TASK_DIR} is in the working tree: the chapter writes it in a copy"
    assert docs_snippets.in_copy(PAGE)
    skipped = [s.code.split()[:2] for s in docs_snippets.snippets(PAGE) if s.check_only]
    assert skipped == [["rerun", "outputs/my_push/episode.rrd"], ["newton-lab", "pipeline"]], (
        "only the viewer and the full pipeline are not run"
    )
    text = PAGE.read_text()
    assert "push_cube/" not in "".join(written.values()), "the written files must not import PushCube's modules"
    assert "--8<--" not in text, "the chapter writes its files; it includes none of the repository's"


def test_every_id_is_named_unique_and_new():
    """The page says which ids must be unique, the Mimic one included, and none of them is taken."""
    from newton_lab.task_api.catalog import declared_task_ids

    ids = _ids(_written()[f"{TASK_DIR}/__init__.py"])
    assert len(ids) == 2 and any("Mimic" in i for i in ids), ids
    section = PAGE.read_text().split("## What must be unique", 1)[1].split("\n## ", 1)[0]
    for task_id in ids:
        assert f"`{task_id}`" in section, f"{task_id} is registered but the page's uniqueness section omits it"
    assert "mimic_variant" in section and "already registered" in section
    assert not set(ids) & set(declared_task_ids()), "an id the chapter registers is taken by a shipped task"


def test_commands_write_into_outputs_only():
    for snippet in docs_snippets.snippets(PAGE):
        if snippet.lang != "bash":
            continue
        for line in docs_snippets.commands(snippet.code):
            words = shlex.split(line)
            for flag, value in zip(words, words[1:]):
                if flag in PATH_FLAGS:
                    assert value.startswith("outputs/"), f"{snippet.where}: {flag} {value} is outside outputs/"


def test_every_output_block_follows_a_command_and_states_its_tolerance():
    found = docs_snippets.outputs(PAGE)
    text_blocks = PAGE.read_text().count("```text")
    assert len(found) == text_blocks - 1, "every text block but the folder tree of step 1 is a compared output"
    assert docs_snippets.check_outputs(PAGE) == []
    assert all(o.after is not None for o in found)


def test_output_comparison():
    compare = docs_snippets.compare_output
    printed = 'noise\n{"task": "T-v0", "episodes": 8, "average_length": 74.0, "wall_time_s": 3.2}\n'
    assert compare('{"task": "T-v0", "episodes": 8,\n "average_length": 75.0, ...}', printed, "5 %") is None
    assert compare('{"task": "T-v0", "episodes": 8, "average_length": 75.0, ...}', printed, "exact")
    assert compare('{"task": "T-v0", "episodes": 9, ...}', printed, "structure") is None
    assert compare('{"task": "T-v1", ...}', printed, "structure"), "names are compared exactly"
    assert compare('{"task": "T-v0", "successes": 8, ...}', printed, "structure"), "a missing key differs"
    assert compare("0.0588", "0.05884", "1 %") is None and compare("0.0588", "0.0600", "1 %")
    assert compare("-0.3950", "-0.3952", "0.001") is None and compare("-0.3950", "-0.3970", "0.001")


@pytest.mark.slow
def test_the_chapter_builds_my_push_in_a_scratch_copy(tmp_path):
    """A reader's run of the whole page, in a copy of the working tree: it writes the task, lists, steps, renders,
    evaluates the expert, collects, runs Mimic, trains and evaluates the policy; every shown output matches."""
    result = docs_snippets.run_in_copy(PAGE, tmp_path / "repo")
    assert result["failed"] is None, (
        f"{result['failed']}: {result['error']}\n{result['trace']}\n{result.get('log', '')[-4000:]}"
    )
    assert sorted(result["wrote"]) == sorted(_written())
    assert result["outputs_compared"] == len(docs_snippets.outputs(PAGE))
    assert result["stray"] == [], f"the page's commands left files outside outputs/: {result['stray']}"
    copy = tmp_path / "repo"
    assert (copy / "outputs" / "my_push" / "policy" / "checkpoint.pt").is_file()
    assert (copy / "outputs" / "my_push" / "end.png").is_file()
    assert not (ROOT / TASK_DIR).exists()
