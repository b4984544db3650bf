"""``newton-lab suite`` (every headline row of the results page, one product command each, records copied, page
rebuilt) and ``newton-lab results`` (the page's headline tables from the committed run records)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..commands import ResultsArgs, SuiteArgs
from ..flows.settings import configure
from ..flows.suite_rows import rows_of
from ..results import update
from . import watchdog


def suite(args: SuiteArgs) -> int:
    rows = rows_of(args.recipe, args.only)
    if args.dry_run:
        for row in rows:
            print(f"{row.name}: newton-lab {' '.join(row.command(Path(args.out), '<UTC time>'))}")
        return 0
    watchdog.start()  # killed, it leaves neither its Prefect server nor the row's command running
    configure(Path(args.out) / ".prefect")  # before Prefect is imported
    from ..flows.suite import suite as run_suite  # deferred: Prefect is slow to import, and after configure

    summary = run_suite(
        recipe=args.recipe, out=str(Path(args.out).resolve()), records=args.records, page=args.page, only=args.only
    )
    for r in summary["rows"]:
        state = "ok" if r["exit"] == 0 else f"failed (exit {r['exit']})"
        print(f"{r['row']:<32} {state:<18} {r.get('record', '')}")
    print(
        json.dumps(
            {
                "recipe": args.recipe,
                "failed": [r["row"] for r in summary["rows"] if r["exit"] != 0],
                "page": summary.get("page"),
            }
        )
    )
    return 0 if all(r["exit"] == 0 for r in summary["rows"]) else 1


def results(args: ResultsArgs) -> int:
    fresh = update(args.page, args.records, check=args.check)
    if args.check and not fresh:
        print(
            f"{args.page} does not match the run records in {args.records}; run `newton-lab results` to regenerate it",
            file=sys.stderr,
        )
        return 1
    print(f"{args.page}: {'up to date' if fresh else 'regenerated'} from {args.records}")
    return 0
