"""The writer process of ``datasets.writers.process`` (:func:`main`, started with the shared ring's descriptor as its
argument): it turns each burst of ended episodes into a ``columns.DemoBlock`` (the low-dim arrays copied out of the
ring, one gather per array; the image frames left in the ring as views, ``files.row_pieces.RowPieces``) and queues the
block on a ``datasets.writers.background_thread.BackgroundWriter``, which writes the queued blocks in batches
(``EpisodeWriter.append_block``: a zarr batch is packed straight from the joined arrays, each chunk of frames
gathered from the ring on the thread that encodes it). A burst's room in the ring goes back (``free``) once its
batch is written; the write queue holds at most half the ring, so a batch is written while the collector fills the
other half.

Replies on stdout, pickled: ``("free", burst)``, ``("written", burst, ids, seconds, batches)``, ``("error", burst,
exception)``; ``seconds`` are the process's own so far: ``write`` (the batch writes), ``copy_out`` (the bursts' low-dim
arrays copied out of the ring), ``queue_wait`` (the main thread blocked on a full write queue, reading no burst
meanwhile) and the zarr store's split of the writes. After a failed batch nothing more is written: every later burst
gets the same error. The process ends at ``close`` or at the end of its stdin (the collector is gone), after writing
what it holds (the ring stays mapped here until then).
"""

from __future__ import annotations

import cProfile
import mmap
import pickle
import sys
import threading
import time
from typing import Any

import numpy as np

from ..storage import EpisodeWriter
from ..zarr import store as zarr_store
from .background_thread import BackgroundWriter
from .child_process import child_pipes
from .columns import DemoBlock


def _timed(append, spent: dict[str, float], profile: cProfile.Profile | None):
    """``append`` (``EpisodeWriter.append_block``) adding its seconds to ``spent["write"]`` (and profiled)."""

    def timed(block: DemoBlock) -> list[int]:
        t0 = time.perf_counter()
        if profile is not None:
            profile.enable()
        try:
            return append(block)
        finally:
            if profile is not None:
                profile.disable()
            spent["write"] += time.perf_counter() - t0

    return timed


def serve(fd: int, inbox, outbox) -> None:
    """Open the dataset, then turn each burst into a block and queue it; reply as ``ProcessWriter`` expects."""
    lock = threading.Lock()

    def reply(message: tuple) -> None:
        with lock:
            pickle.dump(message, outbox, protocol=pickle.HIGHEST_PROTOCOL)
            outbox.flush()

    _, path, task_id, fsync, ring_bytes, layout, settings, zarr_settings, profile_to = pickle.load(inbox)
    buf = mmap.mmap(fd, ring_bytes)
    store = EpisodeWriter.open(path, task_id=task_id, env_args={}, fsync=fsync, zarr_settings=zarr_settings)
    spent = {"write": 0.0, "copy_out": 0.0, "queue_wait": 0.0}
    profile = cProfile.Profile() if profile_to else None
    store.append_block = _timed(store.append_block, spent, profile)  # the batch writes' clock, reported back
    # the queue holds at most half the ring: a put past it has the queue written at once (the frames of queued
    # bursts hold their ring room until written, so a fuller queue would leave the collector waiting for room while
    # the queue waits for its batch to fill)
    writer = BackgroundWriter(
        store, **{**settings, "max_queued_bytes": min(settings["max_queued_bytes"], ring_bytes // 2)}
    )

    def done(burst: int, future) -> None:
        reply(("free", burst))  # its frames were written from the ring: its room goes back now
        if future.exception() is not None:
            reply(("error", burst, _portable(future.exception())))
        else:
            reply(("written", burst, future.result(), {**spent, **zarr_store.BATCH_SECONDS}, writer.batches))

    try:
        while True:
            try:
                message = pickle.load(inbox)
            except EOFError:
                break
            if message[0] == "close":
                break
            _, burst, specs, demos = message
            t0 = time.perf_counter()
            try:
                arrays: dict[str, Any] = {
                    name: np.frombuffer(buf, dtype=dtype, count=int(np.prod(shape)), offset=at).reshape(shape)
                    for name, at, shape, dtype in specs
                }
                # the low-dim columns are copied out; the frames stay in the ring, written from there
                block = DemoBlock.from_rows(layout, arrays.pop(""), arrays, demos, image_views=True)
                del arrays
            except Exception as e:  # noqa: BLE001 - handed to the collector
                reply(("free", burst))
                reply(("error", burst, _portable(e)))
                continue
            t1 = time.perf_counter()
            spent["copy_out"] += t1 - t0
            try:
                future = writer.put_block(block)
            except Exception as e:  # noqa: BLE001 - a failed batch before: nothing more is written
                reply(("free", burst))
                reply(("error", burst, _portable(e)))
                continue
            finally:
                spent["queue_wait"] += time.perf_counter() - t1
            future.add_done_callback(lambda f, b=burst: done(b, f))
    finally:
        try:
            writer.close()
        except Exception:  # noqa: BLE001 - each burst's future already carried it to the collector
            pass
        if profile is not None:
            profile.dump_stats(profile_to)


def _portable(error: BaseException) -> BaseException:
    """``error`` if it survives pickling, else a RuntimeError with its message."""
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:  # noqa: BLE001 - any pickling failure
        return RuntimeError(f"{type(error).__name__}: {error}")


def main() -> None:
    """Entry: the ring's descriptor in ``sys.argv[1]``; messages on stdin, replies on the original stdout."""
    serve(int(sys.argv[1]), *child_pipes())
