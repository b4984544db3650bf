"""Run records and the results page generated from them: what a record holds, that the committed page matches the
committed records (no figure typed by hand), that every record was made by a product command, and the pipeline's
recipe choice on a machine without a GPU (its dry-run plan)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from newton_lab import records, results

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "benchmarks.md"
RECORDS = ROOT / "docs" / "results"


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture: most of these tests never import warp."""
    yield


def _record(kind: str, results_: dict, task: str = "GalbotG1-PickCube-v0", command: str | None = None) -> dict:
    return records.make_record(
        kind,
        task=task,
        device="cpu",
        results=results_,
        wall_s=123.4,
        command=command or f"newton-lab {kind} --task {task}",
    )


def _pipeline_results(successes=97, episodes=100, cameras="front_head=96x72:rgb", sensors=True) -> dict:
    return {
        "recipe": "gpu",
        "seed": 0,
        "cameras": cameras,
        "task_options": {"obs_mode": "sensors"} if sensors else {},
        "counts": {"expert_demos": 16, "expert_success_rate": 1.0, "mimic_demos": 1024, "train_steps": {}},
        "timings_s": {"collect": 1.0},
        "phases": {},
        "success": {"episodes": episodes, "successes": successes, "rate": successes / episodes, "eval_seed": 10000},
    }


def test_a_record_names_command_commit_date_and_device(tmp_path):
    rec = _record("bench", {"env_steps_per_s": 1.0})
    path = records.write_record(rec, tmp_path / "r.json")
    back = records.read_record(path)
    assert back["command"] == "newton-lab bench --task GalbotG1-PickCube-v0"
    assert re.fullmatch(r"[0-9a-f]{40}|unknown", back["commit"]["sha"]) and isinstance(back["commit"]["dirty"], bool)
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", back["date"])
    assert back["device"]["kind"] == "cpu" and back["device"]["cores"] >= 1 and back["wall_s"] == 123.4
    assert back["schema"] == records.SCHEMA and back["versions"]["newton_lab"]
    assert not list(tmp_path.glob(".*.tmp"))  # written atomically
    with pytest.raises(ValueError, match="unknown record kind 'benchh'; valid kinds: pipeline, bench"):
        records.make_record("benchh", task=None, device="cpu", results={})


def test_a_pipeline_record_names_the_kinds_trained_per_target_only_when_given():
    from newton_lab.flows.run_record import StageClock, pipeline_record

    ckpt = {"metrics": {"steps": 5}}
    summary = {
        "task": "GalbotG1-SortToShelf-All-v0",
        "artifacts": {"demos": {"metrics": {"episodes": 2}}, "checkpoints": {"pick/red_cube": ckpt, "place": ckpt}},
        "evaluation": {"episodes": 2, "successes": 0, "success_rate": 0.0},
        "learned_phases": ["pick/red_cube", "place"],
        "stage_states": {},
    }
    settings = {"seed": 0, "device": "cpu", "train_cfg": {}, "cameras": "none", "task_options": {}, "recipe": "cpu"}
    rec = pipeline_record(summary, StageClock(), **settings, per_target=["pick"])["results"]
    assert rec["per_target"] == ["pick"] and rec["counts"]["train_steps"] == {"pick/red_cube": 5, "place": 5}
    assert "per_target" not in pipeline_record(summary, StageClock(), **settings, per_target=[])["results"]
    assert "phase_targets" not in rec, "recorded where the evaluation has it"
    from newton_lab.flows.long_horizon import summary_lines

    by_target = {"pick": {"red_cube": {"reached": 2, "passed": 1}, "blue_cuboid": {"reached": 1, "passed": 0}}}
    summary["evaluation"].update(phases={}, phase_targets=by_target)
    assert pipeline_record(summary, StageClock(), **settings)["results"]["phase_targets"] == by_target
    ckpt.update(path="policy_pick-red_cube/checkpoint.pt", metrics={"steps": 5, "final_loss": 0.5})
    segments = {"pick/red_cube": 3, "nav": 4}
    summary["artifacts"]["phases"] = {k: {"metrics": {"episodes": n}} for k, n in segments.items()}
    lines = summary_lines(summary, "out")
    assert "  phase pick/red_cube 3 segments; policy 5 steps, final loss 0.5000" in lines
    assert "  phase nav           4 segments; expert" in lines
    assert "    pick by target red_cube 1/2, blue_cuboid 0/1" in lines


def test_the_cli_command_line_is_what_the_record_names(monkeypatch):
    monkeypatch.delenv("NEWTON_LAB_COMMAND", raising=False)
    records.set_invocation(["bench", "--task", "GalbotG1-PickCube-v0", "--resolution", "96 72"])
    assert records.command_line() == "newton-lab bench --task GalbotG1-PickCube-v0 --resolution '96 72'"
    monkeypatch.setenv("NEWTON_LAB_COMMAND", "make demo")
    assert records.command_line() == "make demo"
    monkeypatch.setenv("NEWTON_LAB_COMMIT", "abc123+dirty")
    assert records.commit() == {"sha": "abc123", "dirty": True}


def test_unreadable_and_foreign_records_are_refused_in_one_line(tmp_path):
    (tmp_path / "cut.json").write_text('{"schema": 1, "kind"')
    with pytest.raises(ValueError, match=r"run record .*cut.json is unreadable .*; re-run its command"):
        records.read_record(tmp_path / "cut.json")
    (tmp_path / "cut.json").unlink()
    (tmp_path / "other.json").write_text('{"name": "x"}')
    with pytest.raises(ValueError, match="lacks .*'command'.*not written by a newton-lab command"):
        records.read_record(tmp_path / "other.json")
    (tmp_path / "other.json").unlink()
    records.write_record(_record("bench", {}, command="bash run.sh"), tmp_path / "script.json")
    with pytest.raises(ValueError, match="made by 'bash run.sh', not a product command"):
        results.load_records(tmp_path)


def test_tables_are_generated_from_records_with_a_link_each(tmp_path):
    recs = tmp_path / "results"
    records.write_record(_record("pipeline", _pipeline_results()), recs / "demo-gpu.json")
    records.write_record(
        _record(
            "bench",
            {
                "num_envs": 4096,
                "env_steps_per_s": 1_051_029.0,
                "ratio_env_step_to_bare": 1.032,
                "camera": "front_head",
                "resolution": [96, 72],
                "camera_data": ["rgb"],
                "env_steps_per_s_with_camera": 258_800.0,
                "ratio_camera_env_to_ceiling": 0.98,
            },
        ),
        recs / "bench-gpu.json",
    )
    records.write_record(
        _record("bench-collect", {"num_envs": 4096, "successful_demos": 16384, "demos_per_hour": 7.19e6}),
        recs / "collect-gpu.json",
    )
    records.write_record(
        _record(
            "bench-collect",
            {
                "num_envs": 2048,
                "successful_demos": 2048,
                "demos_per_hour": 4.54e5,
                "cameras": {"front_head": [96, 72, ["rgb"]]},
                **{"physics_s": 2.7, "record_s": 3.9, "agent_s": 5.0, "hand_over_s": 3.8, "writer_s": 5.3},
            },
        ),
        recs / "collect-cameras-gpu.json",
    )
    page = tmp_path / "benchmarks.md"
    page.write_text(f"# Benchmarks\n\nintro\n\n{results.BEGIN}\nold\n{results.END}\n\n## Methods\n")
    assert results.update(page, recs, check=True) is False  # stale: compare only, nothing written
    assert "old" in page.read_text()
    assert results.update(page, recs) is False and results.update(page, recs, check=True) is True
    text = page.read_text()
    assert text.startswith("# Benchmarks\n\nintro\n\n") and text.endswith("\n## Methods\n")
    row = next(line for line in text.splitlines() if line.startswith("| PickCube | CPU"))
    for part in (
        "gpu",
        "front_head 96x72 RGB + proprioception",
        "16 expert + 1024 Mimic",
        "100 %",
        "**97 / 100** (seed 10000) | – | 2:03",
        "[demo-gpu](results/demo-gpu.json)",
    ):
        assert part in row, (part, row)
    assert "| 1.05 M | step time 1.03x the bare solver's | [bench-gpu](results/bench-gpu.json) |" in text
    assert "front_head 96x72 rgb | 258.8 k | rate 0.98x the physics + render ceiling" in text
    assert (
        "| 4096 | none | 16384 | 7.19 M | – | [collect-gpu](results/collect-gpu.json) |" in text
    )  # no stages recorded
    assert (
        "| 2048 | front_head 96x72 | 2048 | 454.0 k | physics + render 6.6 s, writer 5.3 s, agent 5.0 s, "
        "hand-over 3.8 s |" in text
    )


def test_the_headline_shows_one_run_per_row_and_device_and_the_others_follow():
    """``<row>-<device>.json`` is the row's headline run; ``<row>-<device>-<variant>.json`` (shared GPU, earlier, one
    setting changed) goes to the earlier and variant runs, unless the row has no plain record: then its newest run
    leads."""
    rec = _record("pipeline", _pipeline_results())  # device "cpu"
    dated = {
        "a-cpu": "2026-11-02",
        "a-cpu-shared": "2026-11-09",
        "b-cpu-earlier": "2026-11-01",
        "b-cpu-shared": "2026-11-05",
    }
    recs = [(Path(f"results/{name}.json"), {**rec, "date": f"{day}T00:00:00Z"}) for name, day in dated.items()]
    main, others = results.split_variants(recs)
    assert [p.stem for p, _ in main] == ["a-cpu", "b-cpu-shared"]
    assert [p.stem for p, _ in others] == ["a-cpu-shared", "b-cpu-earlier"]
    block = results.headline(recs, Path("."))
    head, rest = block.split(f"### {results.VARIANTS_TITLE}")
    assert "(results/a-cpu.json)" in head and "(results/b-cpu-shared.json)" in head and "a-cpu-shared" not in head
    assert "(results/a-cpu-shared.json)" in rest and "(results/b-cpu-earlier.json)" in rest


def test_the_stage_table_splits_a_pipelines_time_with_its_env_build_and_steps():
    """Each pipeline record's row gives its stages' wall times (a stage it did not run: a dash), collect's env build
    where recorded, and the training steps of each policy; stages taken from Prefect's cache say so (collect with
    the seconds it took when it ran), a stage partly run (one of two policies cached) shows its time."""
    res = _pipeline_results()
    res["timings_s"] = {"collect": 258.8, "split": 23.4, "train": 445.4, "evaluate": 44.9}
    res["collect_seconds"] = {"env_build": 110.5}
    res["counts"]["train_steps"] = {"pick": 6221, "place": 6221}
    (row,) = results.stage_rows([(Path("p.json"), _record("pipeline", res))], Path("."))
    assert row[3:9] == ["4:19 (1:50 env build)", "–", "0:23", "7:25 (pick 6,221, place 6,221 steps)", "0:45", "2:03"]
    res["stage_states"] = {"collect": ["Cached"], "split": ["Cached"], "train": ["Cached", "Completed"]}
    res["collect_seconds"]["call"] = 136.5
    (row,) = results.stage_rows([(Path("p.json"), _record("pipeline", res))], Path("."))
    assert row[3:7] == [
        "cached (2:16 when it ran, 1:50 of it env build)",
        "–",
        "cached",
        "7:25 (pick 6,221, place 6,221 steps)",
    ]


def test_evaluation_and_training_tables_split_their_time_and_name_each_variant(tmp_path):
    """An evaluation record's row shows policy and env milliseconds per env step and how the policy sampled (eager
    with ``--eager-policy``); a perturbed one goes to the robustness table only. A bench-train row lists every
    variant's samples/s in words, the fastest first in its own column."""
    timing = {"agent_ms_per_step": 11.04, "env_step_ms_per_step": 4.21}
    base = {
        "episodes": 100,
        "successes": 98,
        "success_rate": 0.98,
        "timing": timing,
        "phase_checkpoints": {"pick": "p"},
    }
    evaluated = [
        (Path("graphed.json"), _record("evaluate", base, command="newton-lab evaluate --task T")),
        (Path("eager.json"), _record("evaluate", base, command="newton-lab evaluate --task T --eager-policy")),
        (Path("perturbed.json"), _record("evaluate", {**base, "perturbations": [{"perturbation": "none"}]})),
    ]
    rows = results.evaluation_rows(evaluated, Path("."))
    assert [r[3] for r in rows] == ["CUDA graphs where the device has them", "eager"]
    assert rows[0][2:7] == [
        "phase policies: pick",
        "CUDA graphs where the device has them",
        "**98 / 100**",
        "11.0",
        "4.2",
    ]
    rates = {"EagerTrainStep_samples_per_s": 4_800.0, "CudaGraphTrainStep_bf16_tuned_samples_per_s": 8_100.0}
    trained = [(Path("t.json"), _record("bench-train", {"batch_size": 256, "image_keys": ["a", "b"], **rates}))]
    (row,) = results.training_rows(trained, Path("."))
    assert row[4] == "8.1 k" and row[6] == "eager 4.8 k, graph bf16 tuned 8.1 k"


def test_the_camera_row_names_the_render_order_and_the_sweeps_fastest():
    """A ``bench --render-orders`` record: the camera row says the env's render order, the fastest setting of the
    sweep and Newton's default beside it, and the rate drawing every shape (the robot links the env leaves out
    too), which is not one of the orders; a record without the sweep names its order alone."""
    base = {"num_envs": 4096, "env_steps_per_s": 1e6, "ratio_env_step_to_bare": 1.03, "camera": "front_head"}
    cam = {"env_steps_per_s_with_camera": 180_000.0, "ratio_camera_env_to_ceiling": 0.98}
    sweep = {
        "PIXEL_PRIORITY/64": {"env_steps_per_s_with_camera": 165_700.0},
        "TILED_8x8/64": {"env_steps_per_s_with_camera": 184_100.0},
        "TILED_16x8/64": {"env_steps_per_s_with_camera": 180_000.0},
        "TILED_16x8/64 every shape": {"env_steps_per_s_with_camera": 150_000.0, "rendered_shapes": 127_000},
    }
    swept = _record(
        "bench", {**base, **cam, "render_order": "TILED/64", "rendered_shapes": 49_000, "by_render_order": sweep}
    )
    plain = _record("bench", {**base, **cam, "render_order": "TILED/64"})
    rows = results.env_step_rows([(Path("a.json"), swept), (Path("b.json"), plain)], Path("."))
    assert rows[1][5] == (
        "rate 0.98x the physics + render ceiling; render order TILED/64; fastest of 3 orders TILED_8x8/64 184.1 k, "
        "Newton's default PIXEL_PRIORITY/64 165.7 k; drawing every shape (127000 in the render, not 49000) 150.0 k"
    )
    assert rows[3][5] == "rate 0.98x the physics + render ceiling; render order TILED/64"


def test_bench_refusals_times_each_case_in_a_fresh_process_and_its_table_shows_the_spread(
    tmp_path, monkeypatch, capsys
):
    """Two cases in fresh ``newton-lab`` processes: one refused as the table says, one the table gets wrong (it is
    answered, exit 0, with no line on stderr): exit status 1, that case named on stderr, both in the record, whose
    row shows 1 of 2 refused and the seconds' spread."""
    from newton_lab.cli import bench_refusals, main

    monkeypatch.setattr(
        bench_refusals,
        "CASES",
        [("view nope.hdf5", "dataset nope.hdf5 does not exist"), ("--version", "words it never prints")],
    )
    rec_path = tmp_path / "results" / "bench-refusals-cpu.json"
    assert main(["bench-refusals", "--run-record", str(rec_path)]) == 1
    err = capsys.readouterr().err
    assert "not refused as the table says: newton-lab --version (exit 0, one line False" in err
    rec = records.read_record(rec_path)
    r = rec["results"]
    assert rec["kind"] == "bench-refusals" and rec["command"].startswith("newton-lab bench-refusals")
    assert (r["cases"], r["refused"], r["exit_2"], r["unchanged"]) == (2, 1, 1, 2)
    first, second = r["per_case"]
    assert first["refused"] and first["exit"] == 2 and first["one_line"] and first["words"]
    assert not second["refused"] and second["exit"] == 0 and not second["one_line"]
    assert (
        0 < r["wall_s"]["median"] <= r["wall_s"]["p95"] <= r["wall_s"]["max"] == max(first["wall_s"], second["wall_s"])
    )
    assert {s["argv"] for s in r["slowest"]} == {"view nope.hdf5", "--version"} and r["command"] == "newton-lab"
    page = tmp_path / "benchmarks.md"
    page.write_text(f"{results.BEGIN}\n{results.END}\n")
    results.update(page, rec_path.parent)
    row = next(line for line in page.read_text().splitlines() if line.startswith("| CPU"))
    assert "| 2 | 1 / 2 |" in row and f"{r['wall_s']['median']:.2f} / " in row, row
    assert row.endswith("[bench-refusals-cpu](results/bench-refusals-cpu.json) |"), row
    assert main(["bench-refusals", "--only", "nope"]) == 2
    assert "--only nope: no case of the bad-input table runs those commands; its commands: " in capsys.readouterr().err


def test_the_committed_page_matches_the_committed_records():
    """Every headline figure of docs/benchmarks.md comes from a record in docs/results/ made by a product command."""
    loaded = results.load_records(RECORDS)  # refuses a record whose command is not a product command
    assert loaded, "docs/results/ holds no run record"
    assert results.update(PAGE, RECORDS, check=True), "docs/benchmarks.md is stale: run `newton-lab results`"
    text = PAGE.read_text()
    block = text.split(results.BEGIN, 1)[1].split(results.END, 1)[0]
    rows = [
        line
        for line in block.splitlines()
        if line.startswith("| ")
        and not line.startswith("| task")
        and not line.startswith("| preset")
        and not line.startswith("| device")
    ]
    assert rows
    for line in rows:  # each row links a record that exists
        link = re.search(r"\]\((results/[^)]+\.json)\) \|$", line)
        assert link and (PAGE.parent / link.group(1)).is_file(), line
    for path, _ in loaded:  # and each record shows on the page
        assert f"({path.relative_to(PAGE.parent)})" in block, path


def test_recipe_choice_without_a_gpu_is_the_cpu_one_and_the_gpu_one_sees_pixels():
    """The dry-run plan of `newton-lab pipeline` on this machine (no CUDA device): the cpu recipe; the gpu recipe
    asked for by name is the visuomotor one (a camera, obs_mode=sensors, the vision preset under bf16)."""
    run = [sys.executable, "-m", "newton_lab.cli", "pipeline", "--task", "GalbotG1-PickCube-v0", "--dry-run"]
    cpu = json.loads(subprocess.run(run, capture_output=True, text=True, check=True, cwd=ROOT).stdout)["plan"]
    assert cpu["recipe"] == "cpu" and cpu["device"] == "cpu" and cpu["cameras"] == "none"
    assert cpu["stages"] == ["collect", "mimic", "train", "evaluate"] and cpu["train_cfg"]["device"] == "cpu"
    gpu = json.loads(
        subprocess.run(run + ["--recipe", "gpu"], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    )["plan"]
    assert (
        gpu["recipe"] == "gpu"
        and gpu["cameras"].startswith("front_head=")
        and gpu["task_options"] == {"obs_mode": "sensors"}
    )
    train = gpu["train_cfg"]
    assert train["device"] == "cuda" and train["bf16"] and train["image_keys"] == ["front_head_rgb"]
    assert "object_pose" not in train["obs_keys"] and "cube_pose" not in train["obs_keys"]

    def shelf_plan(*flags: str) -> dict:
        """The dry-run plan of the PickToShelf pipeline with ``flags``."""
        done = subprocess.run(
            [*run[:4], "--task", "GalbotG1-PickToShelf-v0", "--dry-run", *flags],
            capture_output=True,
            text=True,
            check=True,
            cwd=ROOT,
        )
        return json.loads(done.stdout)["plan"]

    coherent = shelf_plan("--recipe", "gpu")
    assert coherent["long_horizon"] and coherent["stages"][1] == "split" and coherent["demos"] >= 600
    assert shelf_plan("--domain-randomize", "camera_shift=mild")["domain_randomize"] == {"camera_shift": 2.0}
    refused = subprocess.run([*run, "--domain-randomize", "friction=mild"], capture_output=True, text=True, cwd=ROOT)
    assert refused.returncode == 2 and "Mimic" in refused.stderr and len(refused.stderr.strip().splitlines()) == 1
    assert shelf_plan("--distractors", "2")["distractors"] == 2
    refused = subprocess.run([*run, "--distractors", "1"], capture_output=True, text=True, cwd=ROOT)
    assert refused.returncode == 2 and "collect --distractors N" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
