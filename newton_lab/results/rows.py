"""The rows of the results page's tables, one function per table: each takes the (path, record) pairs and the
page's folder and returns the table's cells (figures formatted, every row linking its record)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..records import EVERY_SHAPE, stage_seconds


def _short(task: str | None) -> str:
    return (task or "–").replace("GalbotG1-", "").replace("-v0", "")


def _options(rec: dict[str, Any]) -> str:
    opts = {k: v for k, v in (rec["results"].get("task_options") or {}).items() if k != "obs_mode"}
    return "".join(f" `{v}`" for v in opts.values())


def _task(rec: dict[str, Any]) -> str:
    """A record's task, short, with its task options' values (``SortToShelf `red_cube```)."""
    return f"{_short(rec['task'])}{_options(rec)}"


def _mmss(seconds: float | None) -> str:
    if seconds is None:
        return "–"
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}:{s:02d}"


def _rate(x: float | None) -> str:
    return "–" if x is None else f"{100 * x:.0f} %"


def _k(x: float | None) -> str:
    """A rate per second or hour in thousands (k) or millions (M)."""
    if x is None:
        return "–"
    return f"{x / 1e6:.2f} M" if x >= 1e6 else f"{x / 1e3:.1f} k"


def _sees(res: dict[str, Any]) -> str:
    cams = res.get("cameras") or "none"
    sensors = (res.get("task_options") or {}).get("obs_mode") == "sensors"
    if cams == "none":
        return "state (object poses)" if not sensors else "proprioception"
    views = ", ".join(c.split(":")[0].replace("=", " ") for c in cams.split(","))
    return f"{views} RGB + proprioception" if sensors else f"{views} RGB + state"


def _link(path: Path, page_dir: Path) -> str:
    return f"[{path.stem}]({os.path.relpath(path, page_dir)})"


def _of_kind(records, kind: str):
    """The (path, record) pairs of ``records`` whose kind is ``kind``."""
    return [(path, rec) for path, rec in records if rec["kind"] == kind]


def policy_rows(records, page_dir: Path) -> list[list[str]]:
    rows = []
    for path, rec in _of_kind(records, "pipeline"):
        res = rec["results"]
        s, counts = res["success"], res["counts"]
        learned = f"**{s['successes']} / {s['episodes']}** (seed {s['eval_seed']})"
        data = f"{counts.get('expert_demos')} expert" + (
            f" + {counts['mimic_demos']} Mimic" if counts.get("mimic_demos") else ""
        )
        if res.get("domain_randomize"):  # the robust recipe: collection's rows drew these axes
            data += ", randomised " + ", ".join(f"{k}={v:g}" for k, v in res["domain_randomize"].items())
        if res.get("distractors"):  # collected among distractor objects
            data += f", among {res['distractors']} distractors"
        phases = res.get("phases") or {}
        per_phase = (
            ", ".join(f"{k} {v['passed']}/{v['reached']}" for k, v in phases.items()) if len(phases) > 1 else "–"
        )
        rows.append(
            [
                _task(rec),
                rec["device"]["name"],
                res.get("recipe") or "–",
                _sees(res),
                data,
                _rate(counts.get("expert_success_rate")),
                learned,
                per_phase,
                _mmss(rec.get("wall_s")),
                _link(path, page_dir),
            ]
        )
    return rows


def stage_rows(records, page_dir: Path) -> list[list[str]]:
    """One row per pipeline record: where its time went, stage by stage (``results.timings_s``), with collect's env
    build (kernel compiles on a cold cache) and the training steps of each policy where the record has them; a
    stage the run took from Prefect's cache says ``cached`` (collect: with the seconds it took when it ran)."""
    rows = []
    for path, rec in _of_kind(records, "pipeline"):
        res = rec["results"]
        times, collected = res.get("timings_s") or {}, res.get("collect_seconds") or {}
        states, built = res.get("stage_states") or {}, collected.get("env_build")
        steps = res["counts"].get("train_steps") or {}

        def stage(name: str, times=times, states=states) -> str:
            if states.get(name) and all(s == "Cached" for s in states[name]):
                return "cached"
            return _mmss(times.get(name)) if name in times else "–"

        collect = stage("collect")
        if collect == "cached" and collected.get("call") is not None:
            collect += f" ({_mmss(collected['call'])} when it ran"
            collect += f", {_mmss(built)} of it env build)" if built is not None else ")"
        elif built is not None:
            collect += f" ({_mmss(built)} env build)"
        rows.append(
            [
                _task(rec),
                rec["device"]["name"],
                res.get("recipe") or "–",
                collect,
                stage("mimic"),
                stage("split"),
                stage("train")
                + (" (" + ", ".join(f"{k} {v:,}" for k, v in steps.items()) + " steps)" if steps else ""),
                stage("evaluate"),
                _mmss(rec.get("wall_s")),
                _link(path, page_dir),
            ]
        )
    return rows


def _first_at(curve: list[dict[str, Any]], min_success: float) -> str:
    """Training seconds of the first curve row whose episodes succeeded at least ``min_success`` of the time."""
    return _mmss(next((c["wall_s"] for c in curve if (c.get("success_rate") or 0.0) >= min_success), None))


def rl_rows(records, page_dir: Path) -> list[list[str]]:
    rows = []
    for path, rec in _of_kind(records, "train-rl"):
        r = rec["results"]
        curve = r.get("curve_rows") or []
        last = curve[-1] if curve else {}
        steps, seconds = last.get("env_steps"), last.get("wall_s", r.get("wall_s"))
        ev = r.get("evaluation")
        learned = f"**{ev['successes']} / {ev['episodes']}** (seed {ev['eval_seed']})" if ev else "–"
        rows.append(
            [
                _task(rec),
                rec["device"]["name"],
                str(r.get("num_envs", "–")),
                str(r.get("iterations")),
                _k(steps / seconds if steps and seconds else r.get("env_steps_per_s")),  # the run's mean
                _mmss(seconds),
                _first_at(curve, 0.9),
                learned,
                _mmss(rec.get("wall_s")),
                _link(path, page_dir),
            ]
        )
    return rows


def env_step_rows(records, page_dir: Path) -> list[list[str]]:
    rows = []
    for path, rec in _of_kind(records, "bench"):
        r = rec["results"]
        views = r.get("cameras") or (
            {r["camera"]: [*(r.get("resolution") or ("?", "?")), r.get("camera_data") or ["rgb"]]}
            if r.get("camera")
            else {}
        )
        camera = ", ".join(f"{name} {w}x{h} {'+'.join(data)}" for name, (w, h, data) in views.items()) or "none"
        rows.append(
            [
                _short(rec["task"]),
                rec["device"]["name"],
                str(r["num_envs"]),
                "none",
                _k(r["env_steps_per_s"]),
                f"step time {r['ratio_env_step_to_bare']:.2f}x the bare solver's",
                _link(path, page_dir),
            ]
        )
        if views:
            rows.append(
                [
                    _short(rec["task"]),
                    rec["device"]["name"],
                    str(r["num_envs"]),
                    camera,
                    _k(r.get("env_steps_per_s_with_camera")),
                    (
                        f"rate {r['ratio_camera_env_to_ceiling']:.2f}x the physics + render ceiling"
                        if "ratio_camera_env_to_ceiling" in r
                        else "–"
                    )
                    + _render_orders(r),
                    _link(path, page_dir),
                ]
            )
    return rows


def _render_orders(r: dict[str, Any]) -> str:
    """``bench --render-orders``' sweep in a phrase: the env's render order, the fastest, Newton's default, and the
    env's setting drawing every shape (the robot links it leaves out too)."""
    sweep = r.get("by_render_order")
    if not sweep:
        return f"; render order {r['render_order']}" if r.get("render_order") else ""
    every = {k: v for k, v in sweep.items() if k.endswith(EVERY_SHAPE)}
    rate = {k: v["env_steps_per_s_with_camera"] for k, v in sweep.items() if k not in every}
    best = max(rate, key=rate.get)
    default = next((k for k in rate if k.startswith("PIXEL_PRIORITY/64")), None)
    words = f"; render order {r['render_order']}; fastest of {len(rate)} orders {best} {_k(rate[best])}"
    words += f", Newton's default {default} {_k(rate[default])}" if default else ""
    for v in every.values():
        words += f"; drawing every shape ({v['rendered_shapes']} in the render, not {r['rendered_shapes']}) "
        words += _k(v["env_steps_per_s_with_camera"])
    return words


def collection_rows(records, page_dir: Path) -> list[list[str]]:
    rows = []
    for path, rec in _of_kind(records, "bench-collect"):
        r = rec["results"]
        cams = ", ".join(f"{name} {w}x{h}" for name, (w, h, _) in (r.get("cameras") or {}).items()) or "none"
        rows.append(
            [
                _short(rec["task"]),
                rec["device"]["name"],
                str(r.get("num_envs", "–")),
                cams,
                str(r.get("successful_demos", r.get("episodes", "–"))),
                _k(r.get("demos_per_hour")),
                _stages(r),
                _link(path, page_dir),
            ]
        )
    return rows


def _stages(r: dict[str, Any]) -> str:
    """A collection's stages (``records.stage_seconds``), largest first, in seconds."""
    if "hand_over_s" not in r:
        return "–"
    ranked = sorted(stage_seconds(r).items(), key=lambda kv: -kv[1])
    return ", ".join(f"{name} {s:.1f} s" for name, s in ranked)


VARIANT_WORDS = {
    "EagerTrainStep": "eager",
    "CudaGraphTrainStep": "graph",
    "compiled": "compiled",
    "bf16norms": "bf16 norms",
    "nativenorms": "native norms",
    "bf16": "bf16",
    "cl": "channels-last",
    "tuned": "tuned",
}
"""How ``bench-train``'s variant keys (``CudaGraphTrainStep_bf16_tuned``) read on the page."""


def _variant(key: str) -> str:
    return " ".join(VARIANT_WORDS.get(part, part) for part in key.split("_"))


def training_rows(records, page_dir: Path) -> list[list[str]]:
    rows = []
    for path, rec in _of_kind(records, "bench-train"):
        r = rec["results"]
        rates = {k.removesuffix("_samples_per_s"): v for k, v in r.items() if k.endswith("_samples_per_s")}
        tflops = r.get("achieved_tflops")
        rows.append(
            [
                r.get("preset", "–"),
                rec["device"]["name"],
                str(r.get("batch_size")),
                ", ".join(r.get("image_keys") or []) or "state",
                _k(max(rates.values(), default=None)),
                "–" if tflops is None else f"{tflops:.1f}",
                ", ".join(f"{_variant(k)} {_k(v)}" for k, v in rates.items()) or "–",
                _link(path, page_dir),
            ]
        )
    return rows


def _load(rec: dict[str, Any]) -> str:
    """The host's 1-minute load average when the record was written, of its cores (above 1: the CPU was shared)."""
    load, cores = rec["device"].get("load_average_1_5_15"), rec["device"].get("cores")
    return "–" if not load else f"{load[0]:.1f} on {cores} cores"


def refusal_rows(records, page_dir: Path) -> list[list[str]]:
    rows = []
    for path, rec in _of_kind(records, "bench-refusals"):
        r = rec["results"]
        wall, cpu = r["wall_s"], r["cpu_s"]
        slowest = r["slowest"][0] if r.get("slowest") else None
        rows.append(
            [
                rec["device"]["name"],
                str(r["cases"]),
                f"{r['refused']} / {r['cases']}",
                f"{r['under_2_s']} / {r['cases']}",
                f"{wall['median']:.2f} / {wall['p95']:.2f} / {wall['max']:.2f}",
                f"{cpu['median']:.2f} / {cpu['max']:.2f}",
                _load(rec),
                f"`{slowest['argv']}` {slowest['wall_s']:.2f} s" if slowest else "–",
                _link(path, page_dir),
            ]
        )
    return rows


def _evaluated_agent(rec: dict[str, Any]) -> str:
    """What an ``evaluate`` record ran: its phase policies (by phase), its checkpoint's folder, or the expert. Records
    written before ``phase_checkpoints`` was recorded name their phases in the command (``--phase-checkpoint``)."""
    r = rec["results"]
    phases = r.get("phase_checkpoints") or {}
    if not phases and "--phase-checkpoint" in rec["command"]:
        args = rec["command"].split("--phase-checkpoint", 1)[1].split(" --", 1)[0].split()
        phases = dict(a.partition("=")[::2] for a in args if "=" in a)
    if phases:
        return "phase policies: " + ", ".join(phases)
    if r.get("checkpoint"):
        return Path(r["checkpoint"]).parent.name or Path(r["checkpoint"]).name
    return "expert"


def robustness_rows(records, page_dir: Path) -> list[list[str]]:
    """One row per evaluation of an ``evaluate --perturb`` record."""
    rows = []
    for path, rec in _of_kind(records, "evaluate"):
        r = rec["results"]
        agent = _evaluated_agent(rec)
        for cell in r.get("perturbations") or []:
            rows.append(
                [
                    _task(rec),
                    rec["device"]["name"],
                    agent,
                    f"`{cell['perturbation']}`",
                    f"**{cell['successes']} / {cell['episodes']}**",
                    _link(path, page_dir),
                ]
            )
    return rows


def evaluation_rows(records, page_dir: Path) -> list[list[str]]:
    """One row per ``evaluate`` record without perturbations that timed its loop: where an evaluation's time goes."""
    rows = []
    for path, rec in _of_kind(records, "evaluate"):
        r = rec["results"]
        timing = r.get("timing")
        if r.get("perturbations") or not timing:
            continue
        rows.append(
            [
                _task(rec),
                rec["device"]["name"],
                _evaluated_agent(rec),
                "eager" if "--eager-policy" in rec["command"] else "CUDA graphs where the device has them",
                f"**{r['successes']} / {r['episodes']}**",
                f"{timing['agent_ms_per_step']:.1f}",
                f"{timing['env_step_ms_per_step']:.1f}",
                _mmss(rec.get("wall_s")),
                _link(path, page_dir),
            ]
        )
    return rows
