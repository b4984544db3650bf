"""The curated mutations of ``tools/mutations.py`` (``make mutate``): each breaks one promise of the README with a
small exact text patch, and names the tests that must catch it. Add one here when a new promise gets its tests."""

from __future__ import annotations

from dataclasses import dataclass


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
        "    if finite and not bool(torch.isfinite(actions).all()):\n",
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
        "tests/test_rewards.py::test_a_gripper_closed_beside_the_cube_or_on_its_corner_earns_no_grasp_reward",
    ),
    one_patch(
        "grasp-reward-for-pinching-a-corner",
        "The reward's grasp stage pays only for the object between the fingers, not for fingers stopped on its corner",
        "tasks/common/terminations.py",
        "        return wp.abs(p[1] - finger_middle(ctx, w)) < max_offset and p[0] < ctx.fingertip_reach",
        "        return p[0] < ctx.fingertip_reach",
        "tests/test_rewards.py::test_a_gripper_closed_beside_the_cube_or_on_its_corner_earns_no_grasp_reward",
    ),
    one_patch(
        "lift-reward-for-a-cube-on-the-table",
        "A lift stage pays the fraction of the lift done: nothing for an object grasped on the table",
        "tasks/common/rewards.py",
        "return wp.clamp((entity_pos(ctx, w, entity)[2] - from_z) / span, 0.0, 1.0)",
        "return wp.clamp(0.5 + (entity_pos(ctx, w, entity)[2] - from_z) / span, 0.0, 1.0)",
        "tests/test_rewards.py::test_a_gripper_closed_beside_the_cube_or_on_its_corner_earns_no_grasp_reward",
    ),
    one_patch(
        "lift-cube-without-a-success-stage",
        "LiftCube's reward keeps a quarter for the lifted cube itself (its success stage)",
        "tasks/lift_cube/config/g1/env_cfg.py",
        """            Stage("success", lifted_and_grasped),\n""",
        "",
        "tests/test_rewards.py::test_a_gripper_closed_beside_the_cube_or_on_its_corner_earns_no_grasp_reward",
    ),
    one_patch(
        "ppo-steps-nan-actions-unnoticed",
        "PPO's vec env refuses NaN or inf actions (checked on the device, raised once an iteration)",
        "newton_lab/policies/rl/vec_env.py",
        "nonfinite = (~torch.isfinite(mapped).all()).to(torch.float64)",
        "nonfinite = torch.zeros((), dtype=torch.float64, device=self.device)",
        "tests/test_rl.py::test_the_vec_env_counts_on_the_device_and_refuses_non_finite_actions_once_an_iteration",
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
    one_patch(
        "object-size-never-reaches-the-solver",
        "A perturbation axis changes what the physics simulates (the solver's copy), not only the model's arrays",
        "newton_lab/envs/perturb.py",
        "    env.solver.notify_model_changed(newton.ModelFlags.SHAPE_PROPERTIES)\n\n\ndef _scale_friction",
        "\n\ndef _scale_friction",
        "tests/test_env_perturbations.py::test_object_size_scales_the_objects_shapes_alone_per_row_the_solver_and_pictures_follow",
    ),
)
