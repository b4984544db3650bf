"""The user guide cannot rot: the site builds with ``mkdocs build --strict`` and every link of the built HTML
resolves; every code block of ``docs/`` is checked (Python compiles, each ``newton-lab`` flag exists as written, a
listing shows its file's lines) and the runnable ones run, page by page, at their smallest size
(``tools/docs_snippets.py``); the generated references hold what the code declares."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))  # tools/ is no package

import docs_snippets  # noqa: E402

pytestmark = pytest.mark.slow
BIN = Path(sys.executable).parent
MAX_PICTURE_BYTES = 200_000


class _Links(HTMLParser):
    """The ``href`` / ``src`` targets and the element ids of one HTML page."""

    def __init__(self):
        super().__init__()
        self.targets: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        for key in ("href", "src"):
            if a.get(key) and not (tag == "link" and a.get("rel") in ("canonical", "alternate")):
                self.targets.append(a[key])


def _parse(path: Path) -> _Links:
    links = _Links()
    links.feed(path.read_text(errors="replace"))
    return links


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    proc = subprocess.run(
        [str(BIN / "mkdocs"), "build", "--strict", "-d", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-5000:]
    assert "WARNING" not in log, log[-5000:]
    return out


def test_every_page_is_built_and_every_link_resolves(site):
    pages = sorted(site.rglob("*.html"))
    for md in docs_snippets.pages():
        rel = md.relative_to(docs_snippets.DOCS).with_suffix("")
        built = site / (rel.parent if rel.name == "index" else rel) / "index.html"
        assert built.is_file(), f"{md} was not built (missing from nav?)"
    parsed = {p: _parse(p) for p in pages}
    broken = []
    for page, links in parsed.items():
        for target in links.targets:
            url = urlsplit(target)
            if url.scheme or target.startswith("//") or target.startswith("mailto:"):
                continue
            base = site if url.path.startswith("/") else page.parent  # 404.html links from the site's root
            dest = page if not url.path else (base / unquote(url.path).lstrip("/")).resolve()
            if dest.is_dir():
                dest = dest / "index.html"
            if not dest.exists():
                broken.append(f"{page.relative_to(site)} -> {target}")
            elif url.fragment and dest.suffix == ".html":
                ids = parsed[dest].ids if dest in parsed else _parse(dest).ids
                if unquote(url.fragment) not in ids:
                    broken.append(f"{page.relative_to(site)} -> {target} (no such anchor)")
    assert not broken, "\n".join(broken)


def test_generated_references_hold_what_the_code_declares(site):
    from newton_lab.cli import COMMANDS
    from newton_lab.robots.g1 import spec
    from newton_lab.task_api.catalog import declared_task_ids

    tasks = (site / "tasks" / "index.html").read_text()
    assert all(task_id in tasks for task_id in declared_task_ids())
    assert "sorting_object" in tasks and "front_head" in tasks
    robot = (site / "robot" / "index.html").read_text()
    assert all(joint in robot for group in spec.JOINT_GROUPS.values() for joint in group)
    assert all(mount in robot for mount in spec.CAMERA_MOUNTS)
    cli = (site / "cli" / "index.html").read_text()
    assert all(f'id="{name}"' in cli for name in COMMANDS)


def test_every_snippet_passes_its_check():
    problems = [
        p for page in docs_snippets.pages() for s in docs_snippets.snippets(page) for p in docs_snippets.check(s)
    ]
    problems += [p for page in docs_snippets.pages() for p in docs_snippets.check_outputs(page)]
    assert not problems, "\n".join(problems)


def test_a_flag_that_disappears_fails_the_check():
    check = docs_snippets.check_cli
    assert check("newton-lab collect --task GalbotG1-PushCube-v0 --episodes 2") == []
    assert check("newton-lab collect --no-such-flag 3")  # unknown
    assert check("newton-lab collect --episode 3")  # argparse would take the prefix; the check does not
    assert check("newton-lab no-such-command")
    listing = docs_snippets.Snippet(
        "x.md", 1, "python", "SCENE = 'not the file'\n", "listing", "tasks/push_cube/scene.py"
    )
    assert docs_snippets.check(listing)


def test_shrink_cuts_sizes_and_training():
    line = docs_snippets.shrink("newton-lab train --dataset-path d.hdf5 --preset cpu --time-budget-s 600")
    assert line.endswith("--max-steps 2") and "--time-budget-s" not in line
    assert "--episodes 2 --num-envs 2" in docs_snippets.shrink("newton-lab collect --episodes 100 --num-envs 50")
    assert "num_envs=2, episodes=1" in docs_snippets.shrink_python("make_env(num_envs=4, episodes=1)")


def test_pictures_are_small_and_used():
    text = "".join(p.read_text() for p in docs_snippets.pages())
    for picture in (docs_snippets.DOCS / "images").iterdir():
        assert picture.stat().st_size < MAX_PICTURE_BYTES, f"{picture} is over {MAX_PICTURE_BYTES} bytes"
        assert f"images/{picture.name}" in text, f"{picture} is on no page"


RUNNABLE = [
    str(p.relative_to(ROOT))
    for p in docs_snippets.pages()
    if any(s.check_only is None for s in docs_snippets.snippets(p)) and not docs_snippets.in_copy(p)
]
"""Pages run here, in one process from empty folders; a page that runs in a scratch copy of the repository (the
tutorial's first chapter) has a test file of its own (tests/test_tutorial_simple_task.py)."""


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, dict]:
    """Every page's runnable snippets, run in one process (imports and compiled kernels shared)."""
    work = tmp_path_factory.mktemp("docs_run")
    out = work / "results.json"
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "tools" / "docs_snippets.py"),
            "run",
            *RUNNABLE,
            "--workdir",
            str(work),
            "--json",
            str(out),
        ],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert out.is_file(), (proc.stdout + proc.stderr)[-5000:]
    return {r["page"]: r for r in json.loads(out.read_text())}


@pytest.mark.parametrize("page", RUNNABLE)
def test_page_snippets_run(runs, page):
    result = runs[page]
    assert result["failed"] is None, f"{result['failed']}: {result['error']}\n{result['trace']}"
    assert result["ran"] > 0
