"""Time promises come from run records, never typed: no sentence of the README or the user guide puts a duration
next to ``make demo``, ``make test`` or the test suite; the demo's wall time appears only where a page asks for it
(``<!-- figure: demo_cpu -->``, ``demo_gpu``), and the docs hook fills it from the newest committed record of
that recipe (``tools/docs_tables.py``), linked to the record."""

from __future__ import annotations

import json
import re
import shutil
import sys
from pathlib import Path
from types import SimpleNamespace

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))  # tools/ is no package

import docs_hooks  # noqa: E402
import docs_tables  # noqa: E402

SUBJECT = re.compile(r"`make demo`|make demo\b|`make test`|make test\b|\b(?:the|test|whole) suite\b", re.I)
DURATION = re.compile(
    r"\b\d+(?:[.,]\d+)?\s*(?:minutes?|mins?|hours?|seconds?|s|h)\b|\b\d+:\d\d\b|"
    r"\b(?:a|an|one|two|three|four|five|ten|fifteen|twenty|few)\s+(?:minutes?|hours?)\b|"
    r"\b(?:two|three|four|five|ten|fifteen|twenty|few)\s+seconds\b",
    re.I,
)
GENERATED = re.compile(r"<!-- results: generated.*?<!-- results: end -->", re.S)


def _prose_pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _sentences(text: str):
    text = GENERATED.sub("", text)
    for paragraph in re.split(r"\n\s*\n", text):
        yield from re.split(r"(?<=[.!?])\s+", " ".join(paragraph.split()))


def typed_promises(text: str) -> list[str]:
    """Sentences of ``text`` that state a duration of the demo or the suite by hand."""
    return [s for s in _sentences(text) if SUBJECT.search(s) and DURATION.search(s)]


def test_no_page_types_a_time_for_the_demo_or_the_suite():
    found = [f"{page.relative_to(ROOT)}: {s}" for page in _prose_pages() for s in typed_promises(page.read_text())]
    assert not found, "typed time promises (use <!-- figure: demo_cpu --> or link Benchmarks):\n" + "\n".join(found)


def test_the_scan_finds_typed_promises():
    assert typed_promises("`make demo` runs the pipeline (about 5 minutes).")
    assert typed_promises("The suite runs in about 7 minutes on 2 cores.")
    assert typed_promises("make demo   # the PickCube pipeline on the CPU (about 5 minutes)")
    assert typed_promises("It fits in the 10 minutes the README promises for make demo.")
    assert not typed_promises("`make demo` took <!-- figure: demo_cpu -->. Training takes 600 s.")
    assert not typed_promises("make test builds a second environment.")


def test_the_home_page_asks_for_both_demo_figures():
    text = (ROOT / "docs" / "index.md").read_text()
    assert "<!-- figure: demo_cpu -->" in text and "<!-- figure: demo_gpu -->" in text


def _record(folder: Path, name: str, recipe: str, date: str, wall_s: float, kind: str = "cpu") -> None:
    base = json.loads((ROOT / "docs" / "results" / "pickcube-demo-h200.json").read_text())
    base.update(date=date, wall_s=wall_s, command="make demo")
    base["device"] = {"kind": kind, "name": "x86_64", "count": 1, "cpu": "x86_64", "cores": 2}
    base["results"]["recipe"] = recipe
    (folder / name).write_text(json.dumps(base))


def test_the_demo_figure_is_the_newest_record_of_its_recipe(tmp_path, monkeypatch):
    monkeypatch.setattr(docs_tables, "RESULTS", tmp_path)
    assert "not recorded yet" in docs_tables.demo_figure("cpu", "index.md")
    _record(tmp_path, "old.json", "cpu", "2026-11-01T00:00:00Z", 300.0)
    _record(tmp_path, "new.json", "cpu", "2026-11-29T00:00:00Z", 576.4)
    _record(tmp_path, "gpu.json", "gpu", "2026-12-01T00:00:00Z", 100.0, kind="cuda")
    text = docs_tables.demo_figure("cpu", "index.md")
    assert "9:36" in text and "(results/new.json)" in text and "2 CPU cores" in text and "2026-11-29" in text
    assert "(../results/new.json)" in docs_tables.demo_figure("cpu", "tutorial/simple_task.md")
    assert "1:40" in docs_tables.demo_figure("gpu", "index.md")


def test_the_hook_fills_figures_from_the_committed_records():
    page = SimpleNamespace(file=SimpleNamespace(src_uri="index.md"))
    out = docs_hooks.on_page_markdown("took <!-- figure: demo_gpu --> here", page, None, None)
    found = docs_tables.demo_record("gpu")
    if found is None:
        assert "not recorded yet" in out
    else:
        path, rec = found
        minutes, seconds = divmod(int(round(rec["wall_s"])), 60)
        assert f"{minutes}:{seconds:02d}" in out and f"results/{path.name}" in out
    assert "<!--" not in out


def test_a_copy_of_the_committed_records_loads(tmp_path):
    """Every committed record is one the figures can read (a product command made it)."""
    for path in (ROOT / "docs" / "results").glob("*.json"):
        shutil.copy(path, tmp_path / path.name)
    from newton_lab.results import load_records

    assert load_records(tmp_path)


def test_the_readme_states_the_recipes_sizes():
    """The README's demo sizes are the recipes' (``newton_lab.flows.settings.DEMO_RECIPES``), the settings the
    records were made with."""
    from newton_lab.flows.settings import DEMO_RECIPES

    text = " ".join((ROOT / "README.md").read_text().split())
    cpu, gpu = DEMO_RECIPES["cpu"], DEMO_RECIPES["gpu"]
    assert (
        f"cpu recipe — {cpu['demos']} expert demos, {cpu['mimic_episodes']} Mimic demos" in text
        and f"{cpu['eval_episodes']} held-out randomised evaluation episodes" in text
    ), "README's cpu recipe"
    assert f"{gpu['demos']} expert demos grown to {gpu['mimic_episodes']} by Mimic" in text, "README's gpu recipe"


FRONT_PAGES = ["README.md", "docs/index.md", "docs/pipelines.md", "docs/contributing.md"]
"""The pages a newcomer reads first; each says what ``make demo`` or the suite costs only through the records."""
DEMO_MARKERS = ("<!-- figure: demo_cpu -->", "<!-- figure: demo_gpu -->")


def test_the_front_pages_give_the_demo_figures_of_the_records():
    """The README, home, Pipelines and Contributing pages state the same demo figures, the records': a page that
    names ``make demo`` shows both generated figures (the newest record of each recipe) or, where no hook runs
    (the README, read on the forge), links the Benchmarks page generated from the same records. None types a
    time for the demo or the suite (``test_no_page_types_a_time_for_the_demo_or_the_suite``); the suite's time
    has no record, so no page states one."""
    problems = []
    for name in FRONT_PAGES:
        text = (ROOT / name).read_text()
        if "make demo" not in text:
            continue
        markers = [m for m in DEMO_MARKERS if m in text]
        links_results = re.search(r"\]\((?:docs/|\.\./)?benchmarks\.md(?:#[\w-]+)?\)", text)
        if name == "README.md":
            if not links_results:
                problems.append(f"{name} names make demo but does not link docs/benchmarks.md")
        elif len(markers) != len(DEMO_MARKERS):
            problems.append(f"{name} names make demo but lacks {set(DEMO_MARKERS) - set(markers)}")
    assert not problems, "\n".join(problems)
    assert "make demo" in (ROOT / "docs" / "pipelines.md").read_text()


NUMBER_WORDS = {
    "one": 1,
    "two": 2,
    "three": 3,
    "four": 4,
    "five": 5,
    "six": 6,
    "ten": 10,
    "fifteen": 15,
    "twenty": 20,
    "thirty": 30,
}
UNIT_S = {"second": 1, "seconds": 1, "s": 1, "minute": 60, "minutes": 60, "min": 60, "hour": 3600, "hours": 3600}
STATED_TIME = re.compile(r"\b(\d+(?:\.\d+)?|few|" + "|".join(NUMBER_WORDS) + r")\s+(" + "|".join(UNIT_S) + r")\b", re.I)
PROSE_ONLY = re.compile(r"```.*?```|<!--.*?-->|`[^`\n]*`", re.S)


def stated_times(text: str) -> list[tuple[str, float | None]]:
    """Durations that ``text``'s prose states (code, inline code and comments left out), in seconds; ``None`` for
    a vague one ("a few minutes")."""
    out = []
    for m in STATED_TIME.finditer(PROSE_ONLY.sub(" ", text)):
        count, unit = m.group(1).lower(), m.group(2).lower()
        value = None if count == "few" else float(NUMBER_WORDS[count] if count in NUMBER_WORDS else count)
        out.append((m.group(0), None if value is None else value * UNIT_S[unit]))
    return out


def test_a_chapter_states_no_cost_but_its_own_budgets():
    """A tutorial chapter's cost is what its commands are told to spend: every duration its prose states is one of
    its own ``--time-budget-s`` values (chapter 1's ten minutes of training); anything else would be a typed
    promise that no record backs."""
    problems = []
    for page in sorted((ROOT / "docs" / "tutorial").glob("*.md")):
        text = page.read_text()
        budgets = {float(b) for b in re.findall(r"--time-budget-s (\d+)", text)}
        problems += [f"{page.name}: '{said}'" for said, seconds in stated_times(text) if seconds not in budgets]
    assert not problems, "durations that are no budget of the page's commands:\n" + "\n".join(problems)


def test_the_scan_reads_stated_times():
    assert stated_times("`--time-budget-s 600` fits the run into ten minutes.") == [("ten minutes", 600.0)]
    assert stated_times("Each command takes a few minutes.") == [("few minutes", None)]
    assert stated_times("<!-- check-only: 5 minutes --> a 5 cm cube, `sleep 3 s`") == []


def test_chapter_3_states_the_compound_figures_of_the_records(tmp_path, monkeypatch):
    """Chapter 3 ends its CPU path and its GPU recipe with the success of the newest pipeline record of each
    recipe on PickToShelf (per phase too), never a typed one."""
    text = (ROOT / "docs" / "tutorial" / "compound_task.md").read_text()
    assert "<!-- figure: picktoshelf_cpu -->" in text and "<!-- figure: picktoshelf_gpu -->" in text
    rec = json.loads((ROOT / "docs" / "results" / "picktoshelf-h200.json").read_text())
    monkeypatch.setattr(docs_tables, "RESULTS", tmp_path)
    assert "not recorded yet" in docs_tables.success_figure("GalbotG1-PickToShelf-v0", "gpu", "index.md")
    for name, date, successes in (("old.json", "2026-11-01T00:00:00Z", 50), ("new.json", "2026-11-29T00:00:00Z", 95)):
        rec.update(date=date)
        rec["results"]["success"]["successes"] = successes
        (tmp_path / name).write_text(json.dumps(rec))
    text = docs_tables.success_figure("GalbotG1-PickToShelf-v0", "gpu", "tutorial/compound_task.md")
    pick = rec["results"]["phases"]["pick"]
    assert "**95 / 100**" in text and f"pick {pick['passed']}/{pick['reached']}" in text
    assert "(../results/new.json)" in text
    assert "not recorded yet" in docs_tables.success_figure("GalbotG1-PickToShelf-v0", "cpu", "index.md")


def test_the_collection_figure_is_the_newest_records_collect_stage():
    """Pipelines' "the expert collects faster than Mimic expands" names the newest record's collect stage."""
    assert "<!-- figure: picktoshelf_gpu_collect -->" in (ROOT / "docs" / "pipelines.md").read_text()
    found = docs_tables.pipeline_record("GalbotG1-PickToShelf-v0", "gpu")
    text = docs_tables.collect_figure("GalbotG1-PickToShelf-v0", "gpu", "pipelines.md")
    if found is None:
        assert "not recorded yet" in text
    else:
        path, rec = found
        res = rec["results"]
        assert f"{res['counts']['expert_demos']} demos in {res['timings_s']['collect']:.0f} s" in text
        assert f"(results/{path.name})" in text
