"""Expert collection throughput (``newton-lab bench-collect``): successful demos/s and per GPU-hour, the seconds split
into the three stages (physics ``env.step``, agent ``agent.act``, writer: the background batch writes) and the loop's
hand-over and final drain (``timing``), in one process (``single``) or on several Dask workers at once
(``workers``). ``summary`` words a result for the terminal: the stages per vector step and whether physics bounds
the run."""

from .single import bench_collect
from .summary import summary
from .workers import bench_collect_on_workers

__all__ = ["bench_collect", "bench_collect_on_workers", "summary"]
