"""Curated mutation run: break one promise of the README at a time in a scratch copy and check its tests notice.

Each :class:`Mutation` is a small exact text patch (one or more hunks) of the code that keeps one promise, and the
pytest arguments (files or node ids) of the tests that claim to cover it. The working tree's files (tracked and
not ignored) are copied once to a scratch folder; each patch is applied there in turn and undone after its run
(never in the working tree: Warp reads ``kernels/`` and ``tasks/`` at kernel build and other runs use them), and
the covering tests run with ``-x`` from the copy, ``PYTHONPATH`` pointing at it. A test failure kills the
mutation; all tests passing lets it survive.

    python tools/mutations.py              run every mutation; exit 1 on a survivor, 2 on an error
    python tools/mutations.py --check      only check that every patch still applies (no pytest)
    python tools/mutations.py --only NAME  the named mutations (repeatable); --list prints them
    python tools/mutations.py --baseline   also run each covering set unmutated first (it must pass)

The copy keeps the installed layout: ``newton_lab/{kernels,tasks,flows,assets}`` are links to the copy's top-level
folders (setup.py maps them there), and a pre-flight import checks that every ``newton_lab`` package resolves
inside the copy, not to the editable install of the working tree.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MAPPED = ("kernels", "tasks", "flows", "assets")
"""Top-level folders setup.py installs as ``newton_lab.<name>``."""
TIMEOUT_S = 900
"""Longest a mutation's covering tests may run [s] (a hang is reported, not counted as a kill)."""


class PatchError(ValueError):
    """A mutation's patch no longer applies to the source (its text is gone or not unique)."""


@dataclass(frozen=True)
class Mutation:
    """One broken promise: ``hunks`` ((path, old text, new text), ...) each applied exactly once, and the pytest
    arguments ``tests`` of the tests that must fail on it."""

    name: str
    promise: str
    hunks: tuple[tuple[str, str, str], ...]
    tests: tuple[str, ...]


def one_patch(name: str, promise: str, path: str, old: str, new: str, *tests: str) -> Mutation:
    """A mutation of one hunk."""
    return Mutation(name, promise, ((path, old, new),), tests)


DIV = "tests/test_divergence.py"
STORE, WRITERS, DURABLE = "tests/test_storage.py", "tests/test_writers.py", "tests/test_mutations_durability.py"
MUTATIONS: tuple[Mutation, ...] = (
    one_patch(
        "divergence-bounds-inf",
        "a finite body past the guard's bounds ends the row as diverged",
        "newton_lab/task_api/cfg.py",
        "return (float(self.max_body_distance), float(self.max_body_linear_speed), float(self.max_body_angular_speed))",
        'return (float("inf"),) * 3',
        DIV,
    ),
    one_patch(
        "divergence-guard-never-triggers",
        "a non-finite or absurd state ends the row as diverged",
        "kernels/fuse.py",
        "        diverged = row_diverged(ctx, w, divergence[0], divergence[1], divergence[2])",
        "        diverged = row_diverged(ctx, w, divergence[0], divergence[1], divergence[2]) and False",
        DIV,
    ),
    Mutation(
        "graph-one-substep-short",
        "the captured step equals eager stepping",
        (
            (
                "newton_lab/envs/launches.py",
                "        for _ in range(self.cfg.decimation):\n",
                "        for _ in range(self.cfg.decimation - getattr(self, '_capturing', 0)):\n",
            ),
            (
                "newton_lab/envs/launches.py",
                "            with wp.ScopedCapture(device=self.model.device) as cap:\n                self.step()\n",
                "            self._capturing = 1\n            with wp.ScopedCapture(device=self.model.device) as cap:\n"
                "                self.step()\n            self._capturing = 0\n",
            ),
        ),
        ("tests/test_env.py",),
    ),
    one_patch(
        "action-clip-removed",
        "each action column is clipped to its range before it becomes a target",
        "kernels/actions.py",
        "    return wp.clamp(scale[c] * actions[w, c], low[c], high[c])\n",
        "    return scale[c] * actions[w, c]\n",
        "tests/test_env.py",
    ),
    one_patch(
        "camera-pose-flipped",
        "camera images look the way the reference's cameras look",
        "newton_lab/robots/g1/cameras.py",
        "ROS_TO_PINHOLE = (1.0, 0.0, 0.0, 0.0)",
        "ROS_TO_PINHOLE = (0.0, 0.0, 0.0, 1.0)",
        "tests/test_cameras.py",
    ),
    one_patch(
        "jog-clip-removed",
        "a teleop jog moves each arm joint target at most 0.05 rad per step",
        "newton_lab/agents/teleop/jog.py",
        "step = np.clip(self._solution - self._command, -self.max_joint_step, self.max_joint_step)",
        "step = self._solution - self._command",
        "tests/test_teleop.py",
    ),
    one_patch(
        "yolo-polygons-mirrored",
        "YOLO label polygons outline the objects in the image",
        "newton_lab/datasets/yolo/labels.py",
        "            out.append((cls, poly / [w, h]))",
        "            out.append((cls, (poly * [1, -1] + [0, h]) / [w, h]))",
        "tests/test_yolo_export.py",
    ),
    one_patch(
        "hdf5-data-not-synced",
        "a committed HDF5 append survives a power cut (data synced before the commit)",
        "newton_lab/datasets/hdf5/journal.py",
        "            jf.close_journal()\n            if fsync:\n                os.fsync(raw.fileno())\n",
        "            jf.close_journal()\n",
        STORE,
        DURABLE,
    ),
    one_patch(
        "hdf5-journal-not-synced",
        "the rollback journal is durable before a byte it saves is overwritten",
        "newton_lab/datasets/hdf5/journal.py",
        "        _write_all(self._journal, blob)\n        if self._fsync:\n",
        "        _write_all(self._journal, blob)\n        if False:\n",
        STORE,
        DURABLE,
    ),
    one_patch(
        "hdf5-commit-before-data",
        "the HDF5 commit (journal removed) comes after the data is durable",
        "newton_lab/datasets/hdf5/journal.py",
        "            jf.close_journal()\n            if fsync:\n                os.fsync(raw.fileno())\n",
        "            jf.close_journal()\n            journal_path(path).unlink()\n            if fsync:\n"
        "                os.fsync(raw.fileno())\n            journal_path(path).touch()\n",
        STORE,
        DURABLE,
    ),
    one_patch(
        "zarr-data-not-synced",
        "a committed zarr batch survives a power cut (files synced before the commit)",
        "newton_lab/datasets/zarr/store.py",
        "            if fsync:\n                sync_tree(stage)\n",
        "            if False:\n                sync_tree(stage)\n",
        STORE,
        DURABLE,
    ),
    one_patch(
        "zarr-commit-before-data",
        "the zarr commit (next_demo_id) comes after the batch's demos are in place",
        "newton_lab/datasets/zarr/store.py",
        "            for name in names:\n                os.rename(",
        "            _commit(data, {NEXT_ID: next_id + len(ids),\n"
        "                           'total': total + sum(int(n) for _, _, n in items),\n"
        "                           'num_demos': count + len(ids)})\n"
        "            for name in names:\n                os.rename(",
        STORE,
        DURABLE,
    ),
    one_patch(
        "zarr-commit-not-synced",
        "append returns only after the zarr commit is durable",
        "newton_lab/datasets/zarr/store.py",
        '            if fsync:\n                fsync_path(path / "data" / "zarr.json")\n',
        '            if False:\n                fsync_path(path / "data" / "zarr.json")\n',
        STORE,
        DURABLE,
    ),
    one_patch(
        "writer-lock-skipped",
        "two writers of one dataset take turns (exclusive lock)",
        "newton_lab/datasets/files/locking.py",
        "        _poll(lambda: fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB), fd, path, deadline)\n",
        "        pass\n",
        WRITERS,
    ),
    one_patch(
        "episode-ids-reused",
        "a new episode never reuses the id of a finished one",
        "newton_lab/datasets/zarr/store.py",
        "        ids = list(range(next_id, next_id + demos))\n",
        "        ids = list(range(demos))\n",
        STORE,
    ),
    one_patch(
        "demo-block-one-step-too-many",
        "a demo written from a column block holds exactly its own steps",
        "newton_lab/datasets/writers/columns.py",
        "        inside = np.arange(span)[None, :] < np.asarray(",
        "        inside = np.arange(span)[None, :] <= np.asarray(",
        "tests/test_writer_process.py",
    ),
    one_patch(
        "next-step-reference-off-by-one",
        "a pack stores an array as a reference only where the bytes repeat",
        "newton_lab/datasets/zarr/derived.py",
        "    shifted[ends[:-1] - 1] = rs[ends[:-1]]",
        "    shifted[ends[:-1]] = rs[ends[:-1] + 1]",
        "tests/test_zarr_derived.py",
        "tests/test_collect_writer.py::test_arrays_that_repeat_others_are_stored_once_and_read_back_byte_identical",
    ),
    one_patch(
        "burst-next-obs-columns-shifted",
        "a burst's next observation is split from its own columns",
        "newton_lab/datasets/writers/columns.py",
        'f"next_obs/{key}": np.ascontiguousarray(f[:, after + a : after + b])',
        'f"next_obs/{key}": np.ascontiguousarray(f[:, after + a - 1 : after + b - 1])',
        "tests/test_writer_process.py",
    ),
    one_patch(
        "writer-process-error-dropped",
        "a write error in collect's writer process reaches the collector",
        "newton_lab/datasets/writers/process_main.py",
        '            reply(("error", burst, _portable(future.exception())))\n',
        '            reply(("written", burst, [], dict(spent), writer.batches))\n',
        "tests/test_writer_process.py",
    ),
    one_patch(
        "contained-check-skipped",
        "no path read from a file reaches outside its folder",
        "newton_lab/datasets/files/inside_root.py",
        "    if target != base and base not in target.parents:\n",
        "    if False:\n",
        "tests/test_contained_paths.py",
    ),
    one_patch(
        "retry-condition-inverted",
        "transient stage failures are retried, input errors are not",
        "flows/stage_runs.py",
        "    return not isinstance(error, INPUT_ERRORS)\n",
        "    return isinstance(error, INPUT_ERRORS)\n",
        "tests/test_flows.py::test_input_error_is_not_retried_and_prints_one_line",
        "tests/test_flows.py::test_transient_error_is_retried",
    ),
    one_patch(
        "rng-not-restored",
        "an interrupted training run resumes bitwise where the uninterrupted one is",
        "newton_lab/policies/train.py",
        'then=lambda: restore_rng(state["rng"])',
        "then=lambda: None",
        "tests/test_train_resume.py",
    ),
    one_patch(
        "ppo-chunk-not-restarted",
        "a resumed PPO run repeats the uninterrupted one (curve and actor)",
        "newton_lab/policies/rl/train.py",
        "vec.restart(cfg.seed + len(curve))",
        "None",
        "tests/test_rl.py::test_the_same_seed_trains_the_same_actor_and_a_resumed_run_repeats_the_uninterrupted_one",
    ),
    one_patch(
        "normaliser-stats-not-saved",
        "a checkpoint carries the normaliser stats its policy was trained with",
        "newton_lab/policies/diffusion.py",
        '"normalizers": {"obs": self.obs_normalizer.state_dict(), "action": self.action_normalizer.state_dict()},',
        '"normalizers": {k: {"low": v.state_dict()["low"] * 0, "high": v.state_dict()["high"] * 0 + 1}\n'
        '                                for k, v in (("obs", self.obs_normalizer),\n'
        '                                             ("action", self.action_normalizer))},',
        "tests/test_policy.py::test_checkpoint_round_trip_and_no_overwrite",
        "tests/test_policy.py::test_checkpoint_carries_the_stats_of_the_training_data",
    ),
    one_patch(
        "journal-rollback-skipped",
        "an HDF5 append killed mid-session is rolled back by the next writer",
        "newton_lab/datasets/hdf5/journal.py",
        "        _rollback(raw, path, fsync)  # a previous writer was killed",
        "        pass  # a previous writer was killed",
        "tests/test_storage.py::test_hdf5_writer_open_across_a_killed_append_rolls_it_back_itself",
        STORE,
    ),
    one_patch(
        "diverged-episode-written",
        "collect never writes an episode that diverged",
        "newton_lab/envs/saver.py",
        'if rec["termination_reason"] == DIVERGED or (self.only_successes and not rec["success"]):',
        'if self.only_successes and not rec["success"]:',
        DIV,
    ),
    one_patch(
        "non-finite-episode-written",
        "collect never writes an episode holding a non-finite value",
        "newton_lab/envs/saver.py",
        "        if not got.finite[row]:\n",
        "        if False:\n",
        DIV,
    ),
    one_patch(
        "non-finite-action-accepted",
        "a NaN or inf action is refused in one line before stepping",
        "newton_lab/envs/checks.py",
        "    if not bool(finite.all()):\n",
        "    if False:\n",
        "tests/test_inputs.py",
    ),
    one_patch(
        "welded-drive-targets-dropped",
        "with idle joints welded, the solver tracks the env's drive targets",
        "newton_lab/envs/drive.py",
        "            solver_target_q[w * coords + j] = target_q[w * full_coords + i]\n",
        "            pass\n",
        "tests/test_physics_settings.py",
    ),
    one_patch(
        "welded-coords-not-read-back",
        "with idle joints welded, env.state follows the solver's coordinates",
        "newton_lab/envs/drive.py",
        "            q[w * full_coords + i] = solver_q[w * coords + j]\n",
        "            pass\n",
        "tests/test_physics_settings.py",
    ),
    one_patch(
        "welded-fingers-frozen",
        "welding keeps a gripper's fingers free with its master joint",
        "newton_lab/robots/weld.py",
        "            if (a in out) != (b in out) and None not in (a, b):\n",
        "            if False:\n",
        "tests/test_physics_settings.py",
    ),
    one_patch(
        "recording-set-unchecked",
        "a dataset refuses demos recorded with other cameras or task options",
        "newton_lab/datasets/storage.py",
        '        check_same_recording(p, meta["env_args"], env, option_defaults)\n',
        "",
        "tests/test_recording_set.py",
    ),
    one_patch(
        "split-written-in-place",
        "a split killed midway leaves nothing that looks finished",
        "newton_lab/datasets/split.py",
        "                path,\n                stage / outs[kind].name,\n",
        "                path,\n                outs[kind],\n",
        "tests/test_interrupts.py::test_a_killed_split_leaves_no_writer_and_nothing_that_looks_finished",
    ),
    one_patch(
        "train-interrupt-saves-nothing",
        "Ctrl-C during train saves the resume point after the step in flight",
        "newton_lab/policies/train_loop.py",
        "                if (checkpointer.due(run.step) or stop) and",
        "                if checkpointer.due(run.step) and",
        "tests/test_interrupts.py::test_ctrl_c_during_train_saves_the_resume_point",
    ),
    one_patch(
        "grasp-reward-for-closing-on-nothing",
        "The reward's grasp stage pays only for fingers closed on something, not for closing beside the object",
        "tasks/common/terminations.py",
        "        return finger_lag(ctx, w) > min_lag",
        "        return finger_lag(ctx, w) > -1.0",
        "tests/test_rewards.py::test_a_gripper_closed_beside_the_cube_earns_no_grasp_reward",
    ),
    one_patch(
        "stack-cube-colours-redrawn",
        "StackCube from pixels: the cubes keep their hue under randomisation",
        "tasks/stack_cube/scene.py",
        "keep_hue=True)",
        "keep_hue=False)",
        "tests/test_cameras.py",
    ),
    one_patch(
        "policy-plans-for-every-row",
        "A phase policy plans only for the rows in its phase, and evaluation only for rows with an episode left",
        "newton_lab/policies/agent.py",
        "replan = asked[self._cursor[asked] >= self._queue.shape[1]]",
        "replan = np.nonzero(self._cursor >= self._queue.shape[1])[0]",
        "tests/test_phase_policies.py",
    ),
    one_patch(
        "graphed-sampling-reads-stale-observations",
        "A captured policy call reads the rows it is asked for, not the last call's observations",
        "newton_lab/policies/graphed.py",
        'entry["obs"][:n].copy_(obs)',
        'entry["obs"][:n].copy_(obs) if size not in self._buckets else None',
        "tests/test_policy_vision.py",
    ),
    one_patch(
        "graphed-sampling-returns-the-padding",
        "A captured policy call returns the actions of the rows it was asked for, not its padded bucket",
        "newton_lab/policies/graphed.py",
        'return entry["out"][:n].clone()',
        'return entry["out"][: entry["out"].shape[0]].clone()',
        "tests/test_policy_vision.py",
    ),
    one_patch(
        "split-copies-the-first-frames",
        "A phase dataset holds the frames of its phase's steps, copied as the source stored them",
        "newton_lab/datasets/hdf5/frames.py",
        "[self.chunks[i] for i in rows]",
        "self.chunks[: len(rows)]",
        "tests/test_stored_frames.py",
    ),
    one_patch(
        "evaluation-acts-for-idle-rows",
        "An evaluation asks the agent to act only for the rows that still have an episode to run",
        "newton_lab/envs/rollout_loop.py",
        "actions = act(env) if not act_for_active_rows or eps.active.all() else act(env, eps.active_rows())",
        "actions = act(env)",
        "tests/test_phase_policies.py",
    ),
)


def patched(text: str, mutation: Mutation, path: str) -> str:
    """``text`` of ``path`` with the mutation's hunks for that file applied; :class:`PatchError` naming the
    mutation if a hunk's old text is not found exactly once."""
    for hunk_path, old, new in mutation.hunks:
        if hunk_path != path:
            continue
        count = text.count(old)
        if count != 1:
            raise PatchError(
                f"mutation {mutation.name}: its patch of {path} no longer applies (the text to replace "
                f"occurs {count} times, expected once): update it in tools/mutations.py"
            )
        text = text.replace(old, new)
    return text


def check(root: Path = REPO, mutations: tuple[Mutation, ...] = MUTATIONS) -> list[str]:
    """One line per mutation whose patch does not apply to ``root`` or whose covering tests are missing."""
    problems = []
    for m in mutations:
        try:
            for path in dict.fromkeys(p for p, _, _ in m.hunks):
                patched((root / path).read_text(), m, path)
        except (PatchError, FileNotFoundError) as e:
            problems.append(str(e))
        problems += [
            f"mutation {m.name}: covering test {t} does not exist"
            for t in m.tests
            if not (root / t.split("::")[0]).is_file()
        ]
    return problems


def scratch_copy(dest: Path) -> None:
    """The working tree's files (tracked, and untracked ones git does not ignore: what the tests here import) into
    ``dest``, with the installed package layout."""
    names = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        check=True,
        capture_output=True,
    ).stdout
    for rel in dict.fromkeys(filter(None, names.decode().split("\0"))):
        src = REPO / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel, follow_symlinks=False)
    for name in MAPPED:
        (dest / "newton_lab" / name).symlink_to(Path("..") / name)


PREFLIGHT = """
import importlib, sys
from pathlib import Path
root = Path(sys.argv[1]).resolve()
for name in ("newton_lab", "newton_lab.kernels", "newton_lab.tasks", "newton_lab.flows", "newton_lab.assets"):
    where = [Path(p).resolve() for p in importlib.import_module(name).__path__]
    if not all(root in p.parents for p in where):
        sys.exit(f"{name} resolves to {where}, not inside the scratch copy {root}")
"""


def environment(copy: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    return {**env, "PYTHONPATH": str(copy)}


def run_tests(copy: Path, tests: tuple[str, ...]) -> tuple[str, float, str]:
    """(outcome, seconds, what to show): ``passed`` (exit 0), ``failed`` (exit 1: the first failed test), else
    ``error`` or ``timeout`` (the output's last lines)."""
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, cwd=copy, env=environment(copy), capture_output=True, text=True, timeout=TIMEOUT_S, check=False
        )
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - t0, f"no result after {TIMEOUT_S} s"
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    outcome = {0: "passed", 1: "failed"}.get(proc.returncode, "error")
    failed = [line.split()[1] for line in lines if line.startswith("FAILED ")]
    return outcome, time.perf_counter() - t0, failed[0] if outcome == "failed" and failed else "\n".join(lines[-6:])


def apply(copy: Path, mutation: Mutation, revert: dict[str, str] | None = None) -> dict[str, str]:
    """Patch the copy (or, with ``revert``, put the saved texts back); returns the original texts by path."""
    saved = {}
    for path in dict.fromkeys(p for p, _, _ in mutation.hunks):
        target = copy / path
        text = target.read_text()
        saved[path] = text
        target.write_text(revert[path] if revert else patched(text, mutation, path))
        for stale in target.parent.glob(f"__pycache__/{target.stem}.*.pyc"):
            stale.unlink()  # a same-size rewrite within the second would reuse the other text's bytecode
    return saved


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check that every patch applies")
    parser.add_argument("--list", action="store_true", help="print the mutations and their covering tests")
    parser.add_argument("--only", action="append", default=[], metavar="NAME", help="run only this mutation")
    parser.add_argument("--baseline", action="store_true", help="run each covering set unmutated first")
    args = parser.parse_args(argv)
    chosen = tuple(m for m in MUTATIONS if not args.only or m.name in args.only)
    unknown = set(args.only) - {m.name for m in MUTATIONS}
    if unknown:
        print(f"unknown mutation(s): {', '.join(sorted(unknown))}; --list names them", file=sys.stderr)
        return 2
    if args.list:
        for m in chosen:
            print(f"{m.name:32s} {m.promise}\n{'':32s} {' '.join(m.tests)}")
        return 0
    problems = check(REPO, chosen)
    for line in problems:
        print(line, file=sys.stderr)
    if problems or args.check:
        print(f"{len(chosen) - len(problems)} of {len(chosen)} mutations apply", file=sys.stderr)
        return 2 if problems else 0
    return run(chosen, args.baseline)


def run(chosen: tuple[Mutation, ...], baseline: bool) -> int:
    """Run every mutation in one scratch copy (restored after each); prints the table, returns the exit code."""
    t_start, rows = time.perf_counter(), []
    with tempfile.TemporaryDirectory(prefix="newton_lab_mutants_") as tmp:
        copy = Path(tmp) / "repo"
        scratch_copy(copy)
        pre = subprocess.run(
            [sys.executable, "-c", PREFLIGHT, str(copy)],
            cwd=copy,
            env=environment(copy),
            capture_output=True,
            text=True,
            check=False,
        )
        if pre.returncode != 0:
            print(f"pre-flight: {pre.stderr.strip()}", file=sys.stderr)
            return 2
        if baseline:
            for tests in dict.fromkeys(m.tests for m in chosen):
                outcome, seconds, tail = run_tests(copy, tests)
                print(f"baseline {' '.join(tests)}: {outcome} ({seconds:.0f} s)", flush=True)
                if outcome != "passed":
                    print(tail, file=sys.stderr)
                    return 2
        print(f"{'mutation':32s} {'result':9s} {'s':>5s}  covering tests -> the first that failed", flush=True)
        for m in chosen:
            saved = apply(copy, m)
            try:
                outcome, seconds, tail = run_tests(copy, m.tests)
            finally:
                apply(copy, m, revert=saved)
            result = {"failed": "killed", "passed": "SURVIVED"}.get(outcome, outcome.upper())
            rows.append(result)
            killer = f" -> {tail}" if result == "killed" else ""
            print(f"{m.name:32s} {result:9s} {seconds:5.0f}  {' '.join(m.tests)}{killer}", flush=True)
            if result not in ("killed", "SURVIVED"):
                print("    " + tail.replace("\n", "\n    "), flush=True)
    killed = rows.count("killed")
    print(f"{killed} of {len(rows)} killed in {time.perf_counter() - t_start:.0f} s", flush=True)
    if any(r not in ("killed", "SURVIVED") for r in rows):
        return 2
    return 0 if killed == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
