"""``tools/mutations.py`` (``make mutate``) stays in step with the source: every curated mutation's patch applies
exactly once and its covering tests exist, so the list cannot rot silently; the scratch copy runs its own code.
No pytest runs of the mutants here (``make mutate`` does those)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("newton_lab_mutations", ROOT / "tools" / "mutations.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_every_mutation_still_applies_to_the_source():
    assert _tool().check(ROOT) == []


def test_mutations_are_named_once_change_code_and_name_their_tests():
    tool = _tool()
    names = [m.name for m in tool.MUTATIONS]
    assert len(names) == len(set(names)) and len(names) >= 16
    for m in tool.MUTATIONS:
        assert m.tests and m.promise and m.hunks, m.name
        assert all(old != new and old for _, old, new in m.hunks), m.name


def test_a_patch_that_no_longer_applies_is_an_error_naming_its_mutation(tmp_path, capsys):
    tool = _tool()
    (tmp_path / "mod.py").write_text("x = 1\nx = 1\n")
    (tmp_path / "tests").mkdir()
    stale = tool.Mutation("stale-example", "p", (("mod.py", "y = 2\n", "y = 3\n"),), ("tests/test_gone.py",))
    twice = tool.Mutation("twice-example", "p", (("mod.py", "x = 1\n", "x = 2\n"),), ("mod.py",))
    problems = tool.check(tmp_path, (stale, twice))
    assert problems == [
        "mutation stale-example: its patch of mod.py no longer applies (the text to replace occurs 0 times, "
        "expected once): update it in tools/mutation_cases.py",
        "mutation stale-example: covering test tests/test_gone.py does not exist",
        "mutation twice-example: its patch of mod.py no longer applies (the text to replace occurs 2 times, "
        "expected once): update it in tools/mutation_cases.py",
    ]
    assert tool.main(["--check"]) == 0 and "mutations apply" in capsys.readouterr().err
    assert tool.main(["--only", "no-such-mutation"]) == 2


def test_the_scratch_copy_imports_its_own_code(tmp_path):
    """The mutants run from a copy: every ``newton_lab`` package (kernels/, tasks/, flows/, assets/ mapped in as
    setup.py installs them) resolves inside it, not to the editable install of the working tree, and a change
    made in the copy is the code that runs."""
    tool = _tool()
    copy = tmp_path / "repo"
    tool.scratch_copy(copy)
    env = tool.environment(copy)
    pre = subprocess.run(
        [sys.executable, "-c", tool.PREFLIGHT, str(copy)],
        cwd=copy,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert pre.returncode == 0, pre.stderr[-2000:]
    contained = copy / "newton_lab" / "datasets" / "files" / "inside_root.py"
    contained.write_text(contained.read_text() + "\nMUTANT = True\n")
    probe = "from newton_lab.datasets.files import inside_root; print(inside_root.MUTANT, inside_root.__file__)"
    proc = subprocess.run(
        [sys.executable, "-c", probe], cwd=copy, env=env, capture_output=True, text=True, timeout=300, check=False
    )
    assert proc.returncode == 0 and proc.stdout.split()[0] == "True", proc.stderr[-2000:]
