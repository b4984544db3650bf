"""The suite flow (``newton-lab suite``): every headline row of the results page, one product command per row, run one
after another (so that no row shares the device with another) as task runs of one Prefect flow. Each row is a
``newton-lab`` command in a child process; it writes its own run record, which the suite copies into the records
folder as ``<row>-<device>.json`` before ``newton-lab results`` regenerates the page from them.

A row that fails is reported and the suite goes on with the next one; the summary lists each row's state and
record.
"""

from __future__ import annotations

import datetime as dt
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger, task

from ..records import device_slug, read_record
from ..results import update
from .suite_rows import Row, rows_of


def _newest_record(folder: Path) -> Path | None:
    found = sorted(folder.glob("*.json"), key=lambda p: p.stat().st_mtime)
    return found[-1] if found else None


@task(name="suite row")
def run_row(row: Row, out: str, stamp: str, records: str | None) -> dict[str, Any]:
    """Run one row's command in a child process; copy its record into ``records`` (when given)."""
    log = get_run_logger()
    args = row.command(Path(out), stamp)
    log.info("%s: newton-lab %s", row.name, " ".join(args))
    done = subprocess.run([sys.executable, "-m", "newton_lab.cli", *args], check=False)
    result: dict[str, Any] = {"row": row.name, "exit": done.returncode, "command": "newton-lab " + " ".join(args)}
    if done.returncode != 0:
        log.warning("%s: exit status %d; the suite goes on", row.name, done.returncode)
        return result
    source = (
        _newest_record(Path(out) / row.name / "records")
        if row.is_pipeline
        else Path(out) / "records" / f"{row.name}.json"
    )
    if source is None or not source.is_file():
        result["exit"] = -1
        log.warning("%s: wrote no run record", row.name)
        return result
    record = read_record(source)
    result["record"] = str(source)
    if records:
        target = Path(records) / f"{row.name}-{device_slug(record)}.json"
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, target)
        result["record"] = str(target)
    log.info("%s: record %s", row.name, result["record"])
    return result


@flow(name="suite")
def suite(
    recipe: str = "gpu",
    out: str = "outputs/suite",
    records: str | None = "docs/results",
    page: str | None = "docs/benchmarks.md",
    only: list[str] | None = None,
) -> dict[str, Any]:
    """Run the rows of ``recipe`` one after another; copy each record into ``records`` and regenerate ``page``."""
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    rows = rows_of(recipe, only)
    results = [run_row.submit(row, out, stamp, records).result() for row in rows]
    summary: dict[str, Any] = {"recipe": recipe, "rows": results}
    if records and page and Path(page).is_file():
        update(page, records)
        summary["page"] = page
    (Path(out) / f"suite-{stamp}.json").write_text(json.dumps(summary, indent=1))
    return summary
