"""Prefect flows (imported as ``newton_lab.flows``): ``collect``, ``mimic``, ``train``, ``evaluate`` and
``pipeline`` chaining them over dataset / checkpoint artifacts.

Prefect is imported on first use of a flow, after ``settings.configure`` has set local defaults
(call ``newton_lab.flows.settings.configure(home)`` first to choose where Prefect keeps its state).
"""

from __future__ import annotations

from . import settings

_FLOWS = ("collect", "mimic", "train", "evaluate", "pipeline", "run_pipeline")


def __getattr__(name: str):
    if name in _FLOWS:
        settings.configure()
        from . import orchestration  # deferred: Prefect is slow to import and must follow settings.configure()

        return getattr(orchestration, name)
    raise AttributeError(f"module 'newton_lab.flows' has no attribute {name!r}")


__all__ = list(_FLOWS)
