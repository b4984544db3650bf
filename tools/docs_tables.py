"""Reference tables of the user guide, generated from the code when the site is built (``tools/docs_hooks.py``).

``tasks_page()``: one row per registered task and a section per task (actions, observations, cameras, success,
failures, events, options), from each ``TaskSpec`` and its resolved ``TaskCfg``. ``robot_page()``: the G1's joint
groups with their limits (read from the MJCF), postures, gripper, base, TCP and camera mounts, from the robot spec.
``cli_page()``: every ``newton-lab`` command with its flags, from the parser. Importing the task packages imports
Warp but compiles nothing (about 2 s).
"""

from __future__ import annotations

import ast
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
POSTURES = ROOT / "tasks" / "common" / "config" / "g1" / "postures.py"


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_cell(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def _cell(text: str) -> str:
    """``text`` as one table cell: on one line, pipes escaped."""
    return text.replace("\n", " ").replace("|", "\\|")


def _code(items) -> str:
    return ", ".join(f"`{i}`" for i in items) or "–"


def _name(func) -> str:
    return getattr(func, "__name__", type(func).__name__)


# ------------------------------------------------------------------------------------------------ tasks
def _group_widths() -> dict[str, int]:
    from newton_lab.robots.g1 import spec

    return {group: len(joints) for group, joints in spec.JOINT_GROUPS.items()}


def _actions(cfg) -> str:
    widths = _group_widths()
    return ", ".join(f"`{a.name}` ({a.group}, {a.type}, {widths.get(a.group, '?')})" for a in cfg.actions)


def _action_width(cfg) -> int:
    widths = _group_widths()
    return sum(widths.get(a.group, 0) for a in cfg.actions)


def _cameras(cfg) -> str:
    return ", ".join(f"`{name}` {c.width}×{c.height} {'+'.join(c.data)}" for name, c in cfg.cameras.items()) or "none"


def _observations(cfg) -> str:
    return ", ".join(f"`{k}`" + ("\\*" if t.privileged else "") for k, t in cfg.observations.items())


def _success(cfg) -> str:
    names = [_name(f) for f in cfg.phase_success]
    if cfg.phases:
        return " → ".join(f"{p.name}: `{n}`" for p, n in zip(cfg.phases, names))
    return _code(names)


def _options(spec) -> str:
    parts = []
    for opt in spec.options:
        values = ", ".join(f"`{c}`" for c in opt.choices) if opt.choices else "any"
        parts.append(f"`{opt.name}` ({values})")
    return ", ".join(parts) or "–"


def _task_rows():
    import newton_lab.tasks  # noqa: F401  (registers every task id)

    from newton_lab.task_api.registry import list_tasks, lookup

    for task_id in list_tasks():
        spec = lookup(task_id)
        yield spec, spec.make_cfg({})


def _expert(spec) -> str:
    if spec.expert is None:
        return "each phase's component expert (`TaskFlowAgent`)"
    return f"`{type(spec.make_expert({})).__name__}`"


def _physics(cfg) -> str:
    """The task's ``TaskCfg.physics`` in words (solver, capacities, contact filter)."""
    p = cfg.physics
    text = f"{p.iterations} solver / {p.ls_iterations} line-search iterations, {p.cone} cone"
    if p.tolerance is not None:
        text += f", tolerance {p.tolerance:g}"
    caps = [
        f"{v} {what} per world"
        for v, what in ((p.contacts_per_world, "contacts"), (p.constraints_per_world, "constraint rows"))
        if v
    ]
    text += "; " + (", ".join(caps) if caps else "Newton's default capacities")
    if p.contact_filter is None:
        return text + "; every robot collision geom touches every object and the ground"
    touches = "; ".join(
        f"`{g}` touches {', '.join('every object' if t == '*' else f'`{t}`' for t in targets)}"
        for g, targets in p.contact_filter.robot.items()
    )
    return f"{text}; contacts: {touches}; other robot links touch nothing"


def _task_section(spec, cfg) -> str:
    rows = [
        ["description", spec.description],
        ["actions", f"{_actions(cfg)}: {_action_width(cfg)} columns"],
        ["observations", _observations(cfg)],
        ["cameras", _cameras(cfg)],
        ["success", _success(cfg)],
        ["failures", _code(cfg.terminations)],
        ["reset events", _code(cfg.events)],
        ["subtask signals", _code(cfg.signals)],
        ["reward terms", _code(cfg.rewards)],
        [
            "episode length",
            f"{cfg.episode_length_s:g} s ({round(cfg.episode_length_s / (cfg.sim_dt * cfg.decimation))}"
            f" control steps of {cfg.sim_dt * cfg.decimation:g} s)",
        ],
        ["physics", _physics(cfg)],
        ["expert", _expert(spec)],
        ["options", _options(spec) + "; every task also takes `obs_mode` (`state` or `sensors`)"],
        ["teleop contract", f"`{spec.teleop}`" if spec.teleop else "–"],
    ]
    if spec.source_task:
        rows.insert(1, ["expands", f"[`{spec.source_task}`](#{_anchor(spec.source_task)})"])
    return f"### {spec.id}\n\n" + _table(["property", "value"], rows)


def _anchor(task_id: str) -> str:
    return task_id.lower().replace(".", "")


def tasks_page() -> str:
    """The task table and one section per task (markdown)."""
    tasks = list(_task_rows())
    rows = [
        [
            f"[`{s.id}`](#{_anchor(s.id)})",
            s.description,
            f"{_action_width(c)}: " + ", ".join(a.group for a in c.actions),
            _cameras(c),
            _success(c),
            _options(s),
        ]
        for s, c in tasks
    ]
    table = _table(["id", "what", "action columns", "cameras", "success", "options"], rows)
    sections = "\n\n".join(_task_section(s, c) for s, c in tasks)
    note = (
        "Observation terms marked \\* are privileged (an object's pose or a target's position): "
        '`obs_mode="sensors"` drops them.'
    )
    return f"{table}\n\n{note}\n\n{sections}\n"


# ------------------------------------------------------------------------------------------------ robot
def _mjcf_joints() -> dict[str, dict[str, str]]:
    from newton_lab.robots.g1 import spec

    tree = ET.parse(ROOT / "assets" / spec.MJCF_FILE)
    return {j.get("name"): dict(j.attrib) for j in tree.iter("joint") if j.get("name")}


def _joint_rows() -> list[list[str]]:
    from newton_lab.robots.g1 import spec

    joints = _mjcf_joints()
    groups = {
        **spec.JOINT_GROUPS,
        "planar base": spec.BASE_PLANAR_JOINTS,
        "fingers (coupled)": spec.GRIPPER_FINGER_JOINTS,
    }
    rows = []
    for group, names in groups.items():
        for name in names:
            j = joints.get(name, {})
            unit = "m" if j.get("type") == "slide" else "rad"
            limit = f"{j['range'].replace(' ', ' … ')} {unit}" if "range" in j else "unlimited"
            rows.append(
                [
                    f"`{group}`",
                    f"`{name}`",
                    j.get("type", "hinge"),
                    limit,
                    f"{spec.JOINT_VELOCITY_LIMITS[name]:g}" if name in spec.JOINT_VELOCITY_LIMITS else "–",
                ]
            )
    return rows


def _documented_constants(path: Path) -> list[tuple[str, str]]:
    """(name, docstring) of each module-level constant followed by a docstring."""
    source = path.read_text()
    body = ast.parse(source).body
    out = []
    for node, nxt in zip(body, body[1:]):
        if (
            isinstance(node, ast.Assign)
            and len(node.targets) == 1
            and isinstance(node.targets[0], ast.Name)
            and isinstance(nxt, ast.Expr)
            and isinstance(nxt.value, ast.Constant)
            and isinstance(nxt.value.value, str)
        ):
            out.append((node.targets[0].id, nxt.value.value))
    return out


def _mount_rows() -> list[list[str]]:
    from newton_lab.robots.g1 import cameras, spec

    rows = []
    for mount, site in spec.CAMERA_MOUNTS.items():
        body, pos, quat = cameras.site_pose(mount)
        rows.append(
            [
                f"`{mount}`",
                f"`{site}`",
                f"`{body}`",
                ", ".join(f"{x:.4f}" for x in pos),
                ", ".join(f"{x:.4f}" for x in quat),
            ]
        )
    return rows


def _layout_rows() -> list[list[str]]:
    from newton_lab.robots.g1 import spec

    rows = []
    for spec_, cfg in _task_rows():
        if spec_.source_task:
            continue
        col = 0
        cells = []
        for a in cfg.actions:
            n = len(spec.JOINT_GROUPS.get(a.group, ()))
            cells.append(f"{col}–{col + n - 1} `{a.group}`" if n > 1 else f"{col} `{a.group}`")
            col += n
        rows.append([f"`{spec_.id}`", ", ".join(cells)])
    return rows


def robot_page() -> str:
    """The G1 reference (markdown)."""
    from newton_lab.robots.g1 import cameras, spec

    joints = _table(["group", "joint", "type", "range", "speed limit"], _joint_rows())
    from newton_lab.tasks.common.config.g1 import postures as module

    postures = _table(
        ["name", "value", "what"],
        [[f"`{n}`", f"`{getattr(module, n)}`", d.replace("\n", " ")] for n, d in _documented_constants(POSTURES)],
    )
    mounts = _table(
        ["camera", "MJCF site", "body", "position in the body [m]", "rotation xyzw (pinhole frame)"], _mount_rows()
    )
    layouts = _table(["task", "action columns"], _layout_rows())
    facts = _table(
        ["property", "value"],
        [
            ["model", f"`assets/{spec.MJCF_FILE}` (robot name `{spec.ROBOT_NAME}`)"],
            [
                "gripper",
                f"one master joint per hand: {spec.GRIPPER_OPEN:g} open … {spec.GRIPPER_CLOSED:g} closed [rad], "
                f"at most {spec.GRIPPER_VELOCITY_LIMIT:g} rad/s; each finger slides "
                f"{spec.FINGER_TRAVEL_PER_RAD:g} m per rad",
            ],
            [
                "wheels",
                f"radius {spec.WHEEL_RADIUS:g} m, offsets ±{spec.WHEEL_OFFSET_X:g} m (x) and "
                f"±{spec.WHEEL_OFFSET_Y:g} m (y); speeds clipped to ±{spec.WHEEL_VELOCITY_CLIP:g} rad/s "
                f"({spec.NAV_MAX_SPEED:g} m/s)",
            ],
            [
                "TCP",
                f"in `{spec.END_EFFECTOR_LINK['left']}` / `{spec.END_EFFECTOR_LINK['right']}` at "
                f"{tuple(round(x, 4) for x in spec.TCP_OFFSET_POS)} m, rotation {spec.TCP_OFFSET_QUAT} (xyzw)",
            ],
            [
                "cameras",
                f"pinhole: fx = fy = {cameras.focal_px(1):.4f} × width px, principal point at the centre, "
                f"clipping {spec.CAMERA_CLIPPING[0]:g}–{spec.CAMERA_CLIPPING[1]:g} m",
            ],
            ["action order", "all 26 action joints: " + _code(spec.G1_ACTION_JOINT_NAMES)],
        ],
    )
    return (
        f"## Facts\n\n{facts}\n\n## Joints\n\n{joints}\n\n## Postures\n\nDefined in "
        f"`tasks/common/config/g1/postures.py` (they belong to the tasks, not to the robot).\n\n{postures}\n\n"
        f"## Camera mounts\n\n{mounts}\n\n## Action layouts\n\nColumns of each task's action, in order.\n\n"
        f"{layouts}\n"
    )


# ------------------------------------------------------------------------------------------------ cli
def cli_page() -> str:
    """Every ``newton-lab`` command and its flags (markdown)."""
    from newton_lab.cli import COMMANDS, build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")  # argparse keeps subparsers here only
    parts = []
    for name, cmd in COMMANDS.items():
        rows = []
        for action in sub.choices[name]._actions:
            if not action.option_strings or action.dest in ("help", "verbose"):
                continue
            default = "" if action.default in (None, False) else f" (default `{action.default}`)"
            text = (action.help or "").replace("%(default)s", str(action.default)).split(" (default:")[0]
            text = text.replace("[", "\\[").replace("]", "\\]")  # argparse's [A ...] is no link
            rows.append([" ".join(f"`{o}`" for o in action.option_strings), text + default])
        parts.append(f"## {name}\n\n{cmd.help}\n\n" + (_table(["flag", "what"], rows) if rows else ""))
    return "\n\n".join(parts) + "\n"


# ------------------------------------------------------------------------------------------------ perturbations
def perturbations_page() -> str:
    """Every perturbation axis (``newton_lab.task_api.perturbations.AXES``): what applies it, unit, levels, whether
    domain randomisation draws it per row, and what it changes."""
    from newton_lab.task_api.perturbations import AXES, RANDOMIZED_KINDS

    rows = [
        [
            f"`{a.name}`",
            a.acts_on,
            a.unit,
            f"{a.mild:g}",
            f"{a.strong:g}",
            f"{a.neutral:g}",
            "yes" if a.acts_on in RANDOMIZED_KINDS and a.per_row else "no",
            _cell(a.doc),
        ]
        for a in AXES.values()
    ]
    header = ["axis", "acts on", "unit", "mild", "strong", "unchanged at", "`--domain-randomize`", "what changes"]
    return _table(header, rows) + "\n"


# ------------------------------------------------------------------------------------------------ recipes
def recipes_page() -> str:
    """The pipeline's recipes (``newton_lab.flows.settings``): counts, what the policy sees, training."""
    from newton_lab.flows.settings import (
        DEMO_RECIPES,
        LONG_HORIZON_OPTIONS,
        LONG_HORIZON_RECIPES,
        LONG_HORIZON_TASK_RECIPES,
    )

    def training(train: dict) -> str:
        parts = [f"preset `{train['preset']}`" if "preset" in train else "quarter-width U-Net"]
        if train.get("bf16"):
            parts.append("bf16")
        if train.get("time_budget_s"):
            parts.append(f"{train['time_budget_s']:.0f} s")
        elif train.get("max_steps"):
            parts.append(f"{train['max_steps']} steps")
        return ", ".join(parts)

    def sees(recipe: dict, options: dict) -> str:
        cams = recipe.get("cameras", "none")
        if cams == "none":
            return "state"
        views = ", ".join(f"`{c}`" for c in cams.split(","))
        return views + (" + proprioception" if options.get("obs_mode") == "sensors" else " + state")

    rows = [
        [
            f"`{name}`",
            "single task",
            str(r["demos"]),
            str(r["mimic_episodes"]),
            sees(r, r.get("task_options", {})),
            training(r["train"]),
            str(r["eval_episodes"]),
            str(r["num_envs"]),
        ]
        for name, r in DEMO_RECIPES.items()
    ]
    rows += [
        [
            f"`{name}`",
            "coherent task",
            str(r["demos"]),
            "–",
            sees(r, LONG_HORIZON_OPTIONS),
            training(r["train"]) + " per learned phase",
            str(r["eval_episodes"]),
            str(r["num_envs"]),
        ]
        for name, r in LONG_HORIZON_RECIPES.items()
    ]
    for task, own in LONG_HORIZON_TASK_RECIPES.items():  # a coherent task's own counts over the recipe's
        for name, counts in own.items():
            r = {**LONG_HORIZON_RECIPES[name], **counts}
            rows.append(
                [
                    f"`{name}`",
                    f"`{task}`",
                    str(r["demos"]),
                    "–",
                    sees(r, LONG_HORIZON_OPTIONS) + " + the target one-hot",
                    training(r["train"]) + " per learned phase kind",
                    str(r["eval_episodes"]),
                    str(r["num_envs"]),
                ]
            )
    return (
        _table(
            [
                "recipe",
                "task",
                "expert demos",
                "Mimic demos",
                "policy sees",
                "training",
                "evaluation episodes",
                "most env rows",
            ],
            rows,
        )
        + "\n"
    )


# ------------------------------------------------------------------------------------------------ figures
RESULTS = ROOT / "docs" / "results"
DEMO_TASK = "GalbotG1-PickCube-v0"


def pipeline_record(task: str, recipe: str) -> tuple[Path, dict] | None:
    """The newest committed run record of ``newton-lab pipeline`` on ``task`` with ``recipe`` (``cpu`` or
    ``gpu``), by its date; ``None`` when there is none."""
    from newton_lab.results import load_records

    found = [
        (path, rec)
        for path, rec in load_records(RESULTS)
        if rec.get("kind") == "pipeline"
        and rec.get("task") == task
        and (rec.get("results") or {}).get("recipe") == recipe
        and rec.get("wall_s")
    ]
    return max(found, key=lambda item: item[1]["date"]) if found else None


def demo_record(recipe: str) -> tuple[Path, dict] | None:
    """The newest committed run record of the demo pipeline (PickCube) with ``recipe``; ``None`` when none."""
    return pipeline_record(DEMO_TASK, recipe)


def _minutes(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}:{s:02d}"


def _device(rec: dict) -> str:
    dev = rec["device"]
    if dev.get("kind") == "cpu":
        return f"{dev.get('cores', '?')} CPU cores"
    return f"{dev.get('count', 1)}× {dev.get('name', dev.get('kind'))}"


def demo_figure(recipe: str, page: str) -> str:
    """``make demo``'s wall time with ``recipe`` as the newest record states it, linked to that record from the
    page ``page`` (a path under ``docs/``); a sentence saying there is no record yet when there is none."""
    found = demo_record(recipe)
    to_docs = "../" * page.count("/")
    if found is None:
        return (
            f"not recorded yet with the {recipe} recipe (the [Benchmarks]({to_docs}benchmarks.md) page lists "
            "every run record)"
        )
    path, rec = found
    return (
        f"{_minutes(rec['wall_s'])} (min:s) on {_device(rec)}, {rec['date'][:10]} "
        f"([run record]({to_docs}results/{path.name}))"
    )


def success_figure(task: str, recipe: str, page: str) -> str:
    """The held-out success of the newest pipeline record of ``task`` with ``recipe`` (per phase too), with its
    wall time, device and date, linked to the record from ``page``; a sentence saying there is none otherwise."""
    found = pipeline_record(task, recipe)
    to_docs = "../" * page.count("/")
    if found is None:
        return (
            f"not recorded yet with the {recipe} recipe (the [Benchmarks]({to_docs}benchmarks.md) page lists "
            "every run record)"
        )
    path, rec = found
    res = rec["results"]
    won = res["success"]
    phases = res.get("phases") or {}
    per_phase = ", ".join(f"{name} {p['passed']}/{p['reached']}" for name, p in phases.items())
    return (
        f"**{won['successes']} / {won['episodes']}** held-out episodes"
        + (f" ({per_phase} passed/reached)" if len(phases) > 1 else "")
        + f" in {_minutes(rec['wall_s'])} (min:s) on {_device(rec)}, {rec['date'][:10]} "
        f"([run record]({to_docs}results/{path.name}))"
    )


def collect_figure(task: str, recipe: str, page: str) -> str:
    """How many expert demos the newest pipeline record of ``task`` with ``recipe`` collected and in how many
    seconds (its collect stage), on which device, linked to the record from ``page``."""
    found = pipeline_record(task, recipe)
    to_docs = "../" * page.count("/")
    if found is None:
        return f"not recorded yet with the {recipe} recipe"
    path, rec = found
    demos, seconds = rec["results"]["counts"]["expert_demos"], rec["results"]["timings_s"]["collect"]
    return (
        f"{demos} demos in {seconds:.0f} s on {_device(rec)}, {rec['date'][:10]} "
        f"([run record]({to_docs}results/{path.name}))"
    )


FIGURES = {
    "demo_cpu": lambda page: demo_figure("cpu", page),
    "demo_gpu": lambda page: demo_figure("gpu", page),
    "picktoshelf_cpu": lambda page: success_figure("GalbotG1-PickToShelf-v0", "cpu", page),
    "picktoshelf_gpu": lambda page: success_figure("GalbotG1-PickToShelf-v0", "gpu", page),
    "picktoshelf_gpu_collect": lambda page: collect_figure("GalbotG1-PickToShelf-v0", "gpu", page),
}
"""Inline figures (``<!-- figure: NAME -->`` in a page, ``tools/docs_hooks.py``): each is read from a run record,
never typed."""
