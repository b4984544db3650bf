"""The results page's headline tables, generated from run records (``newton_lab.records``) so that no figure is
typed twice: ``newton-lab results`` rewrites the block between ``BEGIN`` and ``END`` in ``docs/benchmarks.md``
from the records in ``docs/results/``, and ``--check`` fails when the page and the records disagree.

Tables: learned policies (per task: expert success, learned success with its episodes and held-out seed, what
the policy sees, time to policy), each pipeline's stage times, PPO runs, evaluations under perturbations,
env-steps/s with and without cameras, expert demos per GPU-hour, evaluation time per env step (policy and env),
training samples/s per variant, seconds from a bad command line to its one-line refusal. Every row names its device
and links its record. The tables show one run per row and device (``split_variants``); the row's earlier and variant
runs follow in tables of their own. ``rows``: one function per table; ``page``: the records read and the page rewritten.
"""

from __future__ import annotations

from .page import (
    BEGIN,
    DEFAULT_PAGE,
    DEFAULT_RECORDS,
    END,
    VARIANTS_TITLE,
    headline,
    load_records,
    render_page,
    split_variants,
    update,
)
from .rows import (
    collection_rows,
    env_step_rows,
    evaluation_rows,
    policy_rows,
    refusal_rows,
    rl_rows,
    robustness_rows,
    stage_rows,
    training_rows,
)

__all__ = [
    "BEGIN",
    "DEFAULT_PAGE",
    "DEFAULT_RECORDS",
    "END",
    "VARIANTS_TITLE",
    "collection_rows",
    "env_step_rows",
    "evaluation_rows",
    "headline",
    "load_records",
    "policy_rows",
    "refusal_rows",
    "render_page",
    "rl_rows",
    "robustness_rows",
    "split_variants",
    "stage_rows",
    "training_rows",
    "update",
]
