"""The rows of the suite (``newton-lab suite``): every headline row of the results page as one ``newton-lab``
command, per recipe. Kept apart from the flow (``suite``) so that ``--dry-run`` and the checks need no Prefect."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

SORTING_OBJECTS = ("red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder")
"""SortToShelf's objects (the task option ``sorting_object``): one row each."""


@dataclass(frozen=True)
class Row:
    """One headline row: its name (the record's file stem) and its ``newton-lab`` arguments, where ``{out}`` is the
    suite's output folder and ``{stamp}`` the suite's UTC start time."""

    name: str
    args: tuple[str, ...]

    def command(self, out: Path, stamp: str) -> list[str]:
        return [a.format(out=out, stamp=stamp) for a in self.args]

    @property
    def is_pipeline(self) -> bool:
        return self.args[0] == "pipeline"


def _pipeline(name: str, task_id: str, recipe: str, *options: str) -> Row:
    return Row(name, ("pipeline", "--task", task_id, *options, "--recipe", recipe, "--out", f"{{out}}/{name}"))


def _bench(name: str, *args: str) -> Row:
    return Row(name, (*args, "--run-record", f"{{out}}/records/{name}.json"))


ROBUST_RANDOMIZATION = "object_mass=mild,object_size=mild,friction=mild,camera_shift=mild,camera_tilt=mild"
"""The robust recipe's domain randomisation: every axis collection can draw per row, at its mild level."""

HELD_OUT_EVALUATION = (
    "--episodes",
    "100",
    "--num-envs",
    "100",
    "--device",
    "cuda:0",
    "--randomize",
    "--seed",
    "10000",
    "--obs-mode",
    "sensors",
)
"""How the evaluation rows evaluate: the pipelines' held-out seed (their seed + 10000), 100 episodes, the policies
seeing what they were trained on (cameras and proprioception)."""

ROBUST_EVALUATION = (*HELD_OUT_EVALUATION, "--perturb", "sweep")
"""How the robustness rows evaluate: held out, 100 episodes a cell, every axis and level of ``--perturb``."""

PICKTOSHELF_PICK_NETWORK = (
    "--dataset-path",
    "{out}/picktoshelf/phases/pick.hdf5",
    "--preset",
    "vision",
    "--obs-keys",
    "robot_joint_pos,gripper_pos",
    "--image-keys",
    "front_head_rgb,left_wrist_rgb",
)
"""bench-train's data and network for the long-horizon recipe's policy: two views and proprioception, on the
PickToShelf row's pick phase dataset."""

PICKTOSHELF_EVALUATION = (
    *HELD_OUT_EVALUATION,
    "--cameras",
    "front_head=96x72:rgb,left_wrist=96x72:rgb",
    "--max-steps",
    "3000",
)
"""How the PickToShelf pipeline evaluates its phase policies (its recipe's views and step limit), as flags."""

ROWS: dict[str, list[Row]] = {
    "gpu": [
        _pipeline("pickcube-demo", "GalbotG1-PickCube-v0", "gpu"),
        _pipeline("picktoshelf", "GalbotG1-PickToShelf-v0", "gpu"),
        # the same, its datasets in zarr (the format bench-collect's two-camera figure writes)
        _pipeline("picktoshelf-zarr", "GalbotG1-PickToShelf-v0", "gpu", "--dataset-format", "zarr"),
        # the robust recipe: the same, its collection's rows drawing physics and camera offsets (docs/robustness.md)
        _pipeline("picktoshelf-robust", "GalbotG1-PickToShelf-v0", "gpu", "--domain-randomize", ROBUST_RANDOMIZATION),
        *[
            _pipeline(f"sorttoshelf-{o}", "GalbotG1-SortToShelf-v0", "gpu", "--sorting-object", o)
            for o in SORTING_OBJECTS
        ],
        _pipeline("sorttoshelf-all", "GalbotG1-SortToShelf-All-v0", "gpu"),
        _pipeline("stackcube-phased", "GalbotG1-StackCube-Phased-v0", "gpu", "--head", "table"),
        *[
            _bench(
                f"rl-{name}",
                "train-rl",
                "--task",
                task,
                "--num-envs",
                "4096",
                "--device",
                "cuda:0",
                "--time-budget-s",
                budget,
                "--eval-episodes",
                "100",
                "--output-dir",
                f"{{out}}/rl-{name}",
                *extra,
            )
            for name, task, budget, extra in (
                ("reach", "GalbotG1-Reach-v0", "120", ()),
                # LiftCube's 20 s episodes gave a 4096-row run 4.5 k episode ends per 25 iterations: few new starts;
                # with absolute arm targets PPO grasped the cube on the table and never lifted it (ActionScales).
                # Without --joint-state the same 120 s on one H200 ended 0/100 held out (record: variant
                # no-joint-state); with it 100/100: a delta actor that sees its targets and joint velocities lifts
                (
                    "liftcube",
                    "GalbotG1-LiftCube-v0",
                    "120",
                    ("--episode-length-s", "6", "--joint-mode", "delta", "--joint-state"),
                ),
                # PickCube's own time limit (3600 s) leaves a row whose cube went out of reach there for the run;
                # its expert takes 137 steps (6.9 s), so 6 s episodes ended before a policy as slow could release
                ("pickcube", "GalbotG1-PickCube-v0", "300", ("--episode-length-s", "12", "--joint-mode", "delta")),
                # the experts: PushCube 72 steps (3.6 s; its limit 15 s), StackCube 275 steps (13.8 s; 3600 s)
                (
                    "pushcube",
                    "GalbotG1-PushCube-v0",
                    "300",
                    ("--episode-length-s", "8", "--joint-mode", "delta", "--joint-state"),
                ),
                (
                    "stackcube",
                    "GalbotG1-StackCube-v0",
                    "400",
                    ("--episode-length-s", "28", "--joint-mode", "delta", "--joint-state"),
                ),
            )
        ],
        _bench(
            "bench-pickcube-4096",
            "bench",
            "--task",
            "GalbotG1-PickCube-v0",
            "--num-envs",
            "4096",
            "--steps",
            "200",
            "--device",
            "cuda:0",
            "--camera",
            "front_head",
            "--resolution",
            "96",
            "72",
        ),
        _bench(
            "bench-pickcube-4096-two-cameras",
            "bench",
            "--task",
            "GalbotG1-PickCube-v0",
            "--num-envs",
            "4096",
            "--steps",
            "200",
            "--device",
            "cuda:0",
            "--cameras",
            "front_head=96x72:rgb,left_wrist=96x72:rgb",
            "--render-orders",  # and under each of the renderer's traversal orders (the same pixels)
        ),
        _bench(
            "bench-collect-pickcube-4096",
            "bench-collect",
            "--task",
            "GalbotG1-PickCube-v0",
            "--num-envs",
            "4096",
            "--episodes",
            "16384",
            "--device",
            "cuda:0",
            "--prefill",
            "0",
            "--dataset-path",
            "{out}/bench_collect_{stamp}/demos.zarr",
        ),
        *[
            _bench(
                f"bench-collect-picktoshelf-cameras{suffix}",
                "bench-collect",
                "--task",
                "GalbotG1-PickToShelf-v0",
                "--num-envs",
                "2048",
                "--episodes",
                "2048",  # one wave; at 4096 rows the episodes' frames, kept on the GPU until they end, do not fit
                "--device",
                "cuda:0",
                "--prefill",
                "0",
                "--cameras",
                "front_head=96x72:rgb,left_wrist=96x72:rgb",
                "--obs-mode",
                "sensors",
                "--dataset-path",
                f"{{out}}/bench_collect_cameras{suffix}_{{stamp}}/demos.{fmt}",
            )
            # zarr (frames in ~1 MB time chunks) and HDF5 (a frame a chunk: the format the pipelines collect in)
            for suffix, fmt in (("", "zarr"), ("-hdf5", "hdf5"))
        ],
        _bench(
            "bench-train-vision",
            "bench-train",
            "--dataset-path",
            "{out}/pickcube-demo/mimic.hdf5",
            "--preset",
            "vision",
            "--batch-size",
            "256",
            "--steps",
            "100",
            "--bf16",
            "--channels-last",
            "--device",
            "cuda",
        ),
        # the network the long-horizon recipe trains (two views, proprioception) on PickToShelf's pick phase data
        _bench(
            "bench-train-vision-picktoshelf-pick",
            "bench-train",
            *PICKTOSHELF_PICK_NETWORK,
            "--batch-size",
            "256",
            "--steps",
            "100",
            "--bf16",
            "--cudnn-benchmark",
            "--bf16-norms",
            "--native-norms",
            "--profile",
            "--device",
            "cuda",
        ),
        # the same network at batch 1024, its GroupNorms through the layer-norm kernels beside PyTorch's own
        _bench(
            "bench-train-vision-picktoshelf-pick-b1024",
            "bench-train",
            *PICKTOSHELF_PICK_NETWORK,
            "--batch-size",
            "1024",
            "--steps",
            "30",
            "--bf16",
            "--bf16-norms",
            "--native-norms",
            "--device",
            "cuda",
        ),
        # the evaluation's time per env step, policy against env, with policy sampling replayed from CUDA graphs and
        # eagerly (--eager-policy), on the PickToShelf row's policies and held-out seed
        *[
            _bench(
                f"evaluate-picktoshelf-{name}-policy",
                "evaluate",
                "--task",
                "GalbotG1-PickToShelf-v0",
                "--phase-checkpoint",
                "pick={out}/picktoshelf/policy_pick/checkpoint.pt",
                "place={out}/picktoshelf/policy_place/checkpoint.pt",
                *PICKTOSHELF_EVALUATION,
                *extra,
            )
            for name, extra in (("graphed", ()), ("eager", ("--eager-policy",)))
        ],
        # off the training distribution: the demo's and PickToShelf's policies (their pipeline rows above) on the
        # held-out seed, unperturbed and under every perturbation axis at each level (100 episodes each)
        _bench(
            "robust-pickcube-demo",
            "evaluate",
            "--task",
            "GalbotG1-PickCube-v0",
            "--checkpoint",
            "{out}/pickcube-demo/policy/checkpoint.pt",
            *ROBUST_EVALUATION,
            "--cameras",
            "front_head=96x72:rgb",
        ),
        _bench(
            "robust-picktoshelf",
            "evaluate",
            "--task",
            "GalbotG1-PickToShelf-v0",
            "--phase-checkpoint",
            "pick={out}/picktoshelf/policy_pick/checkpoint.pt",
            "place={out}/picktoshelf/policy_place/checkpoint.pt",
            *ROBUST_EVALUATION,
            "--cameras",
            "front_head=96x72:rgb,left_wrist=96x72:rgb",
            "--max-steps",
            "3000",
        ),
        _bench(
            "robust-picktoshelf-robust",
            "evaluate",
            "--task",
            "GalbotG1-PickToShelf-v0",
            "--phase-checkpoint",
            "pick={out}/picktoshelf-robust/policy_pick/checkpoint.pt",
            "place={out}/picktoshelf-robust/policy_place/checkpoint.pt",
            *ROBUST_EVALUATION,
            "--cameras",
            "front_head=96x72:rgb,left_wrist=96x72:rgb",
            "--max-steps",
            "3000",
        ),
    ],
    "cpu": [
        _pipeline("pickcube-demo", "GalbotG1-PickCube-v0", "cpu"),
        _bench(
            "bench-pickcube-4",
            "bench",
            "--task",
            "GalbotG1-PickCube-v0",
            "--num-envs",
            "4",
            "--steps",
            "200",
            "--device",
            "cpu",
        ),
        _bench(
            "rl-reach",
            "train-rl",
            "--task",
            "GalbotG1-Reach-v0",
            "--num-envs",
            "128",
            "--device",
            "cpu",
            "--iterations",
            "60",
            "--chunk-iterations",
            "10",
            "--eval-episodes",
            "16",
            "--output-dir",
            "{out}/rl-reach",
        ),
    ],
}
"""The rows of each recipe, in the order they run (bench-train reads the demo's Mimic dataset)."""


def rows_of(recipe: str, only: list[str] | None = None) -> list[Row]:
    """The rows of ``recipe``, or those of them named in ``only`` (one-line error for an unknown name)."""
    if recipe not in ROWS:
        raise ValueError(f"unknown suite recipe {recipe!r}; valid recipes: {', '.join(ROWS)}")
    rows = ROWS[recipe]
    unknown = sorted(set(only or ()) - {r.name for r in rows})
    if unknown:
        raise ValueError(
            f"unknown suite row(s) {unknown}; rows of the {recipe} recipe: {', '.join(r.name for r in rows)}"
        )
    return [r for r in rows if not only or r.name in only]
