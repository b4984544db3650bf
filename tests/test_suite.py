"""``newton-lab suite``: the rows a user runs to reproduce the results page (each a product command), and one row
run end to end on the CPU through the Prefect flow: its record copied as ``<row>-cpu.json`` and the page rebuilt
with a row that links it."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from newton_lab.flows.suite_rows import ROWS, rows_of

from newton_lab.records import is_product_command
from newton_lab.results import BEGIN, END


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture: the suite's rows run in child processes."""
    yield


def test_every_row_is_a_product_command_and_the_gpu_rows_cover_the_headline_tasks(tmp_path):
    for recipe, rows in ROWS.items():
        names = [r.name for r in rows]
        assert len(names) == len(set(names)), recipe
        for row in rows:
            assert is_product_command("newton-lab " + " ".join(row.command(tmp_path, "t"))), row
    tasks = {row.args[row.args.index("--task") + 1] for row in ROWS["gpu"] if row.is_pipeline}
    assert tasks == {
        "GalbotG1-PickCube-v0",
        "GalbotG1-PickToShelf-v0",
        "GalbotG1-SortToShelf-v0",
        "GalbotG1-SortToShelf-All-v0",
        "GalbotG1-StackCube-Phased-v0",
    }
    assert sum("--sorting-object" in r.args for r in ROWS["gpu"]) == 4
    with pytest.raises(ValueError, match=r"unknown suite row\(s\) \['nope'\]; rows of the cpu recipe: pickcube-demo"):
        rows_of("cpu", ["nope"])


def test_a_row_runs_through_the_flow_and_lands_on_the_page(tmp_path):
    page = tmp_path / "benchmarks.md"
    page.write_text(f"# Benchmarks\n\n{BEGIN}\n{END}\n")
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "newton_lab.cli",
            "suite",
            "--recipe",
            "cpu",
            "--only",
            "bench-pickcube-4",
            "--out",
            str(tmp_path / "suite"),
            "--records",
            str(tmp_path / "results"),
            "--page",
            str(page),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    assert json.loads(out.stdout.strip().splitlines()[-1])["failed"] == []
    record = json.loads((tmp_path / "results" / "bench-pickcube-4-cpu.json").read_text())
    assert record["command"].startswith("newton-lab bench --task GalbotG1-PickCube-v0 --num-envs 4")
    assert record["device"]["kind"] == "cpu" and record["results"]["env_steps_per_s"] > 0
    assert "[bench-pickcube-4-cpu](results/bench-pickcube-4-cpu.json)" in page.read_text()
