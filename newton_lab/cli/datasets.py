"""The dataset commands (``split``, ``export``, ``view``): each calls ``newton_lab.datasets`` or ``newton_lab.viz`` on a
recorded dataset with its argument object (``newton_lab.commands.workflow``), prints its result (one JSON line last)
and returns the exit status. The library imports are deferred into the commands: the dataset package imports
Warp/Newton, the LeRobot export pyarrow, the replay rerun-sdk."""

from __future__ import annotations

import json
from pathlib import Path

from ..commands import ExportArgs, SplitArgs, ViewArgs


def split(args: SplitArgs) -> int:
    from ..datasets import split_by_phase, split_train_val  # deferred: the dataset package imports Warp/Newton

    if args.out is None:
        keys = split_train_val(args.dataset_path, args.val_ratio, seed=args.seed, filter_key=args.filter_key)
        print(json.dumps({"path": str(args.dataset_path), "filter_keys": {k: len(v) for k, v in keys.items()}}))
        return 0
    refs = split_by_phase(args.dataset_path, args.out, phases=args.phase_names())
    print(
        json.dumps(
            {name: {"path": str(r.path), "task": r.task_id, "episodes": r["episodes"]} for name, r in refs.items()}
        )
    )
    return 0


def export(args: ExportArgs) -> int:
    from ..datasets.lerobot import export_lerobot  # deferred: pyarrow, Warp/Newton are slow

    out = export_lerobot(args.dataset_path, args.root, include_failed=args.include_failed, video=not args.no_video)
    keys = ("root", "repo_id", "episodes", "frames", "skipped_failed", "fps", "image_keys", "video_files")
    print(json.dumps({k: out[k] for k in keys}))
    return 0


def view(args: ViewArgs) -> int:
    from ..viz import replay_episode  # deferred: rerun-sdk is slow to import

    poses = replay_episode(args.dataset, args.episode, save=args.save, spawn=args.spawn)
    if args.save:
        print(f"rerun recording: {Path(args.save).resolve()} (open it with: rerun {Path(args.save).resolve()})")
    print(json.dumps({"dataset": args.dataset, "episode": args.episode, "frames": len(poses), "rrd": args.save}))
    return 0
