"""A ``torch.profiler`` window over a few vector steps of a timed collection (``bench-collect --trace``)."""

from __future__ import annotations

from pathlib import Path

from torch.profiler import ProfilerActivity, profile, record_function, schedule

TRACE_AFTER_STEPS = 300
"""Vector steps of the timed run before ``--trace`` records, by default: past the first episodes' ends (PickCube's
come after ~150 steps at 4096 rows). The rows start together and their episodes keep ending in bursts, so a
window may catch few ends (on an H200, steps 300-320 of PickCube held few): move it with ``--trace-after``."""
TRACE_STEPS = 20
"""Vector steps ``--trace`` records (a 4096-row PickCube step is ~10 MB of trace with the Python tracer on)."""


class Trace:
    """A ``torch.profiler`` window over ``TRACE_STEPS`` vector steps of the timed run (CPU ops, the Python tracer, and
    on a GPU every kernel and copy of the process, Warp's too, through CUPTI), each stage a labelled range: saved as
    a Chrome trace (``path``, ``.json.gz``: Perfetto opens it) and a table of the costliest operations
    (``<path>.txt``). What a GPU timeline shows and the stage clocks cannot: which host call waits for which kernel."""

    def __init__(self, path: Path, device, after: int = TRACE_AFTER_STEPS) -> None:
        self.path, self.after = path, after
        self.cuda = device.is_cuda
        acts = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if self.cuda else [])
        self.prof = profile(
            activities=acts,
            with_stack=True,
            on_trace_ready=self._save,
            schedule=schedule(wait=after, warmup=2, active=TRACE_STEPS, repeat=1),
        )

    def wrap(self, label: str, fn):
        def labelled(*args, **kwargs):
            with record_function(label):
                return fn(*args, **kwargs)

        return labelled

    def stepping(self, fn):
        """``fn`` (the env step) that moves the trace's window on by one step after each call."""

        def stepped(*args, **kwargs):
            out = fn(*args, **kwargs)
            self.prof.step()
            return out

        return stepped

    def _save(self, prof) -> None:
        prof.export_chrome_trace(str(self.path))
        tables = [f"# {self.path.name}: {TRACE_STEPS} vector steps after {self.after}"]
        keys = (("self_cuda_time_total", "self_device_time_total") if self.cuda else ()) + (
            "cpu_time_total",
            "self_cpu_time_total",
        )
        averages = prof.key_averages()
        for key in keys:
            try:
                tables += [f"\n## by {key}", averages.table(sort_by=key, row_limit=40, max_name_column_width=70)]
            except (AttributeError, KeyError, ValueError):  # the CUDA column's name differs across torch versions
                continue
        Path(f"{self.path}.txt").write_text("\n".join(tables) + "\n")
