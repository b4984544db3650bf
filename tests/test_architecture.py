"""The layering rules of newton_lab, checked on the source with ``ast`` (no imports, no physics).

Layers, lowest first; a module may import its own layer and the ones below, never one above:

    robots, assets  ->  kernels  ->  task_api  ->  tasks  ->  datasets  ->  envs  ->  agents  ->  mimic
    ->  policies  ->  perception  ->  viz  ->  commands, bench, bench_collect, bench_train, cli, flows, records,
    results

Also: no import cycle between modules or between packages, no ``importlib`` of project modules by name,
imports at module top (a deliberately deferred import says ``deferred`` in a comment on its line), no
module over 400 lines, no function over 80 lines except Warp kernels / funcs. The env's narrow surface: no
private attribute of an env object touched outside ``newton_lab/envs/``, at most 30 public names on the env class
and, outside ``envs/``, only those and the names of its parts (``env.sim``, ``env.task``, ``env.sensors``,
``env.joints``, ``env.buffers``), and no run-time patching of project code in the library. The robot behind one
binding: a robot package is imported only by ``robots/`` and by that robot's task configs.
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {
    "newton_lab": "newton_lab",
    "newton_lab.kernels": "kernels",
    "newton_lab.tasks": "tasks",
    "newton_lab.flows": "flows",
    "newton_lab.assets": "assets",
}
LAYERS = [
    ("robots", "assets"),
    ("kernels",),
    ("task_api",),
    ("tasks",),
    ("datasets",),
    ("envs",),
    ("agents",),
    ("mimic",),
    ("policies",),
    ("perception",),
    ("viz",),
    ("commands", "bench", "bench_collect", "bench_train", "cli", "flows", "records", "results"),
]
RANK = {unit: i for i, units in enumerate(LAYERS) for unit in units}
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80


def _modules() -> dict[str, Path]:
    found = {}
    for pkg, folder in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join((pkg, *parts))] = path
    return found


MODULES = _modules()
TREES = {name: ast.parse(path.read_text(), filename=str(path)) for name, path in MODULES.items()}


def _unit(module: str) -> str | None:
    """The layer unit of a project module: ``newton_lab.<unit>...``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def _resolve(module: str, node: ast.ImportFrom) -> list[str]:
    """Project modules named by a ``from ... import ...`` in ``module``."""
    if node.level:
        base = module.split(".") if _is_package(module) else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    if not target.startswith("newton_lab"):
        return []
    names = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in MODULES]
    return names or [target]


def _imports(module: str) -> list[tuple[str, ast.stmt]]:
    out = []
    for node in ast.walk(TREES[module]):
        if isinstance(node, ast.ImportFrom):
            out += [(t, node) for t in _resolve(module, node)]
        elif isinstance(node, ast.Import):
            out += [(a.name, node) for a in node.names if a.name.startswith("newton_lab")]
    return [(t, n) for t, n in out if t in MODULES or any(m.startswith(t + ".") for m in MODULES)]


def _owner(target: str) -> str:
    """The module file that a dotted import target lives in."""
    while target not in MODULES:
        target = target.rsplit(".", 1)[0]
    return target


GRAPH = {m: sorted({_owner(t) for t, _ in _imports(m)} - {m}) for m in MODULES}


def test_every_unit_has_a_layer():
    units = {_unit(m) for m in MODULES} - {None}
    assert units <= set(RANK), f"modules outside the layer list: {sorted(units - set(RANK))}"


CONTRIBUTING = ROOT / "docs" / "contributing.md"
LAYER_LINE = re.compile(r"imports point one way[^:]*:\s*(.*?);", re.S)
"""contributing.md's statement of the layers: units in backticks, ``→`` between layers, ``,`` within one."""


def test_contributing_states_the_layer_order():
    """docs/contributing.md lists the layers this test enforces, in the same order, with the same units."""
    found = LAYER_LINE.search(CONTRIBUTING.read_text())
    assert found, f"{CONTRIBUTING.name}: no 'imports point one way: ...;' line"
    stated = [set(re.findall(r"`([a-z_]+)`", layer)) for layer in found.group(1).split("→")]
    assert stated == [set(units) for units in LAYERS], (
        f"{CONTRIBUTING.name} states the layers {stated}; tests/test_architecture.py's LAYERS are "
        f"{[set(u) for u in LAYERS]}: change the page to match"
    )


def test_no_upward_import():
    bad = []
    for module, targets in GRAPH.items():
        src = _unit(module)
        for target in targets:
            dst = _unit(target)
            if src in RANK and dst in RANK and RANK[dst] > RANK[src]:
                bad.append(f"{module} -> {target} ({src} may not import {dst})")
    assert not bad, "upward imports:\n" + "\n".join(bad)


def _cycle(graph: dict[str, list[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in graph.get(node, ()):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in graph:
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def _package_of(module: str) -> str:
    return module if _is_package(module) else module.rsplit(".", 1)[0]


def test_no_module_cycle():
    # a package's __init__ importing its own submodules is how packages re-export; the cycle that matters is
    # a submodule importing back through an ancestor package
    graph = {m: [t for t in ts if not (_is_package(m) and t.startswith(m + "."))] for m, ts in GRAPH.items()}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_no_package_cycle():
    graph: dict[str, set[str]] = defaultdict(set)
    for module, targets in GRAPH.items():
        src = _package_of(module)
        for target in targets:
            dst = _package_of(target)
            if src != dst and not dst.startswith(src + ".") and not src.startswith(dst + "."):
                graph[src].add(dst)
    cycle = _cycle({k: sorted(v) for k, v in graph.items()})
    assert cycle is None, "package cycle: " + " -> ".join(cycle)


TASK_LOADER = "newton_lab.tasks"
"""The one import by name: the tasks package loads its own subpackages (so a new task touches only its own
folder); it adds no edge between layers."""


def test_no_importlib_of_project_modules():
    bad = []
    for module, tree in TREES.items():
        if module == TASK_LOADER:
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and "import_module" in ast.unparse(node.func):
                bad.append(f"{module}:{node.lineno} {ast.unparse(node)}")
    assert not bad, "importlib by string:\n" + "\n".join(bad)


def test_imports_at_module_top():
    bad = []
    for module, tree in TREES.items():
        lines = MODULES[module].read_text().splitlines()
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, (ast.Import, ast.ImportFrom)) and "deferred" not in lines[node.lineno - 1]:
                    bad.append(f"{module}:{node.lineno} {ast.unparse(node)}")
    assert not bad, "imports inside functions (move them up, or say '# deferred: <why>'):\n" + "\n".join(
        sorted(set(bad))
    )


def test_module_size():
    long = {m: n for m, p in MODULES.items() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


MAX_CLI_MODULE_LINES = 150
"""The command line parses and calls: a feature's work lives in the library, its arguments in ``commands/``."""


def test_the_command_line_parses_and_calls():
    """No ``newton_lab/cli/`` module over ``MAX_CLI_MODULE_LINES`` lines, and every argument dataclass (a class
    named ``...Args``) is defined in ``newton_lab.commands``."""
    long = {
        m: n
        for m, p in MODULES.items()
        if m.startswith("newton_lab.cli") and (n := len(p.read_text().splitlines())) > MAX_CLI_MODULE_LINES
    }
    assert not long, f"command-line modules over {MAX_CLI_MODULE_LINES} lines (move the work into the library): {long}"
    stray = [
        f"{m}.{node.name}"
        for m, tree in TREES.items()
        if not m.startswith("newton_lab.commands")
        for node in ast.walk(tree)
        if isinstance(node, ast.ClassDef) and node.name.endswith("Args")
    ]
    assert not stray, f"argument dataclasses outside newton_lab/commands/: {stray}"


def _is_warp(fn: ast.FunctionDef) -> bool:
    for d in fn.decorator_list:
        name = ast.unparse(d.func if isinstance(d, ast.Call) else d)
        if name in ("wp.kernel", "wp.func", "warp.kernel", "warp.func"):
            return True
    return False


def test_function_size():
    long = []
    for module, tree in TREES.items():
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _is_warp(fn):
                n = fn.end_lineno - fn.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{module}.{fn.name}: {n} lines")
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(long)


@pytest.mark.parametrize("rule", ["tasks import no agents, datasets, envs or mimic"])
def test_tasks_declare_data_only(rule):
    bad = [
        f"{m} -> {t}"
        for m, ts in GRAPH.items()
        if _unit(m) == "tasks"
        for t in ts
        if _unit(t) in ("agents", "datasets", "envs", "mimic", "policies")
    ]
    assert not bad, rule + ":\n" + "\n".join(bad)


# ---------------------------------------------------------------- the env's narrow surface
ENV_SURFACE_FOLDERS = ("newton_lab", "flows", "kernels", "tasks", "examples", "tests", "tools")
"""Source scanned for private access to env objects (every ``.py`` file, ``newton_lab/envs/`` aside)."""
ENV_OWNER = "newton_lab/envs/"
"""The one place that may touch the env's private attributes (and those of its cameras / actuation objects)."""
ENV_OBJECT_NAMES = r"^(.*_)?(env|envs|cams|cameras|actuation|launches|binding)$"
"""How an env object is recognised without running anything: the name it is reached by, the last part of the
expression before the dot (``env``, ``pick_env``, ``self._env``, ``env.sensors.cameras``, ``cams``, ``eager_env``...).
The project names its envs and their parts so everywhere; a private attribute is ``_name`` (not a dunder)."""


def _source_files(folders) -> dict[str, ast.Module]:
    out = {}
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            out[rel] = ast.parse(path.read_text(), filename=rel)
    return out


def _last_name(node: ast.AST) -> str | None:
    """The name an expression ends in: ``env`` for ``env``, ``cameras`` for ``env.sensors.cameras``, ``f`` for
    ``f()``."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, (ast.Call, ast.Subscript)):
        return _last_name(node.func if isinstance(node, ast.Call) else node.value)
    return None


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _private_env_access(files: dict[str, ast.Module]) -> list[str]:
    """``file:line expression`` of every private attribute of an env object read or written outside ``envs/``
    (``env._x``, ``self._env._x``, ``getattr(env, "_x")``)."""
    env_like = re.compile(ENV_OBJECT_NAMES)
    bad = []
    for rel, tree in files.items():
        if rel.startswith(ENV_OWNER):
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and _private(node.attr):
                owner = _last_name(node.value)
            elif (
                isinstance(node, ast.Call)
                and _last_name(node.func) in ("getattr", "setattr", "hasattr")
                and len(node.args) > 1
                and isinstance(node.args[1], ast.Constant)
                and isinstance(node.args[1].value, str)
                and _private(node.args[1].value)
            ):
                owner = _last_name(node.args[0])
            else:
                continue
            if owner is not None and env_like.match(owner):
                bad.append(f"{rel}:{node.lineno} {ast.unparse(node)}")
    return bad


def test_no_private_access_to_env_objects_outside_envs():
    bad = _private_env_access(_source_files(ENV_SURFACE_FOLDERS))
    assert not bad, (
        "private attributes of env objects used outside newton_lab/envs/ (use the env's public surface, "
        "newton_lab/envs/env.py's docstring lists it):\n" + "\n".join(bad)
    )


ENV_CLASS = ("newton_lab/envs/env.py", "NewtonEnv")
ENV_PARTS_FILE = "newton_lab/envs/parts.py"
ENV_PARTS = {
    "sim": "EnvSim",
    "task": "EnvTask",
    "sensors": "EnvSensors",
    "joints": "EnvJoints",
    "buffers": "EnvBuffers",
}
"""The env's named parts: ``env.<part>`` is an object of ``newton_lab/envs/parts.py``'s class."""
MAX_ENV_NAMES = 30
"""Public names the env class defines (attributes, methods, properties): the rest is behind its parts."""
ENV_NAMES = r"^(.*_)?env$"
"""A ``NewtonEnv`` (not its parts, nor a list of envs) is reached by a name ending in ``env``."""
GYMNASIUM_NAMES = {
    "unwrapped",
    "action_space",
    "observation_space",
    "single_action_space",
    "single_observation_space",
    "close",
    "metadata",
    "spec",
    "np_random",
    "render_mode",
}
"""What a gymnasium wrapper named ``env`` in the tests adds (``newton_lab/envs/gym.py``'s classes are read too)."""
NOT_ENV_CALLS = {n for n in dir(dict) + dir(str) if not n.startswith("_")}
"""Methods of the dicts and strings also named ``env`` (a process environment, ``q_env`` rows): never env names."""


def _class_names(path: str, name: str) -> set[str]:
    """Public names class ``name`` of ``path`` defines: methods and properties, class fields, ``self.x = ...``."""
    tree = ast.parse((ROOT / path).read_text())
    cls = next(n for n in ast.walk(tree) if isinstance(n, ast.ClassDef) and n.name == name)
    names = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)}
    for node in ast.walk(cls):
        targets = (
            node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        )
        for t in (e for target in targets for e in (target.elts if isinstance(target, ast.Tuple) else [target])):
            if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id == "self":
                names.add(t.attr)
            elif isinstance(t, ast.Name) and node in cls.body:
                names.add(t.id)
    return {n for n in names if not n.startswith("_")}


def test_the_env_defines_at_most_30_public_names_and_its_parts():
    names = _class_names(*ENV_CLASS)
    assert len(names) <= MAX_ENV_NAMES, f"NewtonEnv defines {len(names)} public names: {sorted(names)}"
    assert set(ENV_PARTS) <= names, f"NewtonEnv lacks its parts {sorted(set(ENV_PARTS) - names)}"


def _off_surface(files: dict[str, ast.Module]) -> list[str]:
    """``file:line expression`` of every ``env.x`` outside ``envs/`` whose ``x`` the env does not define, and every
    ``env.<part>.x`` whose ``x`` that part does not define."""
    gym = {n for c in ("NewtonGymEnv", "NewtonVectorEnv") for n in _class_names("newton_lab/envs/gym.py", c)}
    surface = _class_names(*ENV_CLASS) | gym | GYMNASIUM_NAMES | NOT_ENV_CALLS
    parts = {part: _class_names(ENV_PARTS_FILE, cls) for part, cls in ENV_PARTS.items()}
    env_like, bad = re.compile(ENV_NAMES), []
    for rel, tree in files.items():
        if rel.startswith(ENV_OWNER):
            continue
        modules = {
            a.asname or a.name.split(".")[0]
            for n in ast.walk(tree)
            if isinstance(n, ast.Import | ast.ImportFrom)
            for a in n.names
        }  # ``from . import env``: a module
        for node in ast.walk(tree):
            if not isinstance(node, ast.Attribute) or node.attr.startswith("__"):
                continue
            base = node.value
            named_env = (
                isinstance(base, ast.Name | ast.Attribute)
                and env_like.match(_last_name(base))
                and not (isinstance(base, ast.Name) and base.id in modules)
            )
            if named_env and node.attr not in surface:
                bad.append(f"{rel}:{node.lineno} {ast.unparse(node)} (not on the env)")
            elif (
                isinstance(base, ast.Attribute)
                and base.attr in parts
                and env_like.match(_last_name(base.value) or "")
                and node.attr not in parts[base.attr]
            ):
                bad.append(f"{rel}:{node.lineno} {ast.unparse(node)} (not on env.{base.attr})")
    return bad


def test_code_outside_envs_reaches_the_env_through_its_surface_and_parts():
    bad = _off_surface(_source_files(ENV_SURFACE_FOLDERS))
    assert not bad, (
        "names that are not on the env's surface (newton_lab/envs/env.py) or its parts "
        "(newton_lab/envs/parts.py):\n" + "\n".join(bad)
    )


def test_the_surface_rule_flags_an_old_name_and_a_name_a_part_lacks():
    src = ast.parse("env.step(a)\nenv.joint_coords(n)\npick_env.sim.model\nenv.sim.obs_terms\nenv.task.obs_terms\n")
    assert sorted(b.split(" ", 1)[1] for b in _off_surface({"tests/x.py": src})) == [
        "env.joint_coords (not on the env)",
        "env.sim.obs_terms (not on env.sim)",
    ]


MONKEYPATCH_ALLOWED: set[tuple[str, str]] = set()
"""(file, call) pairs that may still patch project code at run time, each with its reason."""


def _project_names(tree: ast.Module) -> set[str]:
    """Names a module binds by importing project modules or their members (classes, functions, modules)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("newton_lab")):
            names |= {a.asname or a.name for a in node.names}
        elif isinstance(node, ast.Import):
            names |= {a.asname or a.name.split(".")[0] for a in node.names if a.name.startswith("newton_lab")}
    return names


def _run_time_patching(files: dict[str, ast.Module]) -> list[str]:
    """``file:line what`` of every run-time rebinding of project code: ``Cls.method = ...`` / ``module.fn = ...``
    (or ``del``) on an imported project name, ``env.step = ...`` on an env object outside ``envs/``, and
    ``setattr`` / ``delattr`` on anything but ``self`` (``MONKEYPATCH_ALLOWED`` aside)."""
    env_like = re.compile(ENV_OBJECT_NAMES)
    bad = []
    for rel, tree in files.items():
        imported = _project_names(tree)
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, (ast.Assign, ast.Delete)):
                targets = node.targets
            elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
                targets = [node.target]
            flat = [t for target in targets for t in (target.elts if isinstance(target, ast.Tuple) else [target])]
            for t in flat:
                if not isinstance(t, ast.Attribute):
                    continue
                base = t.value
                if isinstance(base, ast.Name) and base.id in imported:
                    bad.append(f"{rel}:{node.lineno} {ast.unparse(t)} (a project name)")
                elif (
                    not rel.startswith(ENV_OWNER)
                    and env_like.match(_last_name(base) or "")
                    and not (isinstance(base, ast.Name) and base.id == "self")
                ):
                    bad.append(f"{rel}:{node.lineno} {ast.unparse(t)} (an env object)")
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id in ("setattr", "delattr")
                and node.args
                and not (isinstance(node.args[0], ast.Name) and node.args[0].id == "self")
                and (rel, node.func.id) not in MONKEYPATCH_ALLOWED
            ):
                bad.append(f"{rel}:{node.lineno} {ast.unparse(node)}")
    return bad


def test_no_monkeypatching_in_the_library():
    """Library code never rebinds attributes of project classes, modules or env objects at run time (a hook or an
    argument does it, e.g. ``env.collect(..., timers=...)``)."""
    bad = _run_time_patching(_source_files(("newton_lab", "flows", "kernels", "tasks")))
    assert not bad, "run-time patching of project code:\n" + "\n".join(bad)


PATCHING = """
from .datasets.storage import EpisodeWriter
from . import zarr_store
EpisodeWriter.append_prepared = wrap(EpisodeWriter.append_prepared)
zarr_store.sync_tree = wrap(zarr_store.sync_tree)
env.step, agent.act = wrap(env.step), wrap(agent.act)
del env.step
setattr(module, "fn", wrap)
setattr(self, "ok", 1)
self.fine = 1
"""
PRIVATE = """
env._graph
pick_env._ctx.phase
self._env._obs
env.sensors.cameras._groups
getattr(cams, "_graph")
other._x
env.__class__
"""


def test_the_surface_rules_catch_what_they_name():
    patches = _run_time_patching({"newton_lab/x.py": ast.parse(PATCHING)})
    assert sorted(p.split(" ", 1)[1] for p in patches) == sorted(
        [
            "EpisodeWriter.append_prepared (a project name)",
            "zarr_store.sync_tree (a project name)",
            "env.step (an env object)",
            "env.step (an env object)",
            "setattr(module, 'fn', wrap)",
        ]
    )
    private = _private_env_access({"tests/x.py": ast.parse(PRIVATE)})
    assert sorted(p.split(" ", 1)[1] for p in private) == sorted(
        ["env._graph", "pick_env._ctx", "self._env._obs", "env.sensors.cameras._groups", "getattr(cams, '_graph')"]
    )
    assert not _private_env_access({ENV_OWNER + "env.py": ast.parse(PRIVATE)})


# ---------------------------------------------------------------- the robot behind one binding
ROBOT_PACKAGES = ("newton_lab.robots.g1",)
"""Robot packages: only the robots layer (the registry loads a built-in robot's registration) and the tasks (a
robot's own task configs) import them; everything else reads the robot through ``env.robot``
(``newton_lab.robots.binding.RobotBinding``, looked up by ``newton_lab.robots.registry.robot_binding``)."""
ROBOT_IMPORT_ALLOWED = {
    # temporary: modules with their own owners that still read G1 facts directly
}
"""Module -> what it still reads from a robot package directly (each entry to be moved onto the binding)."""


def _imports_robot_package(module: str) -> bool:
    return any(t == p or t.startswith(p + ".") for t in GRAPH[module] for p in ROBOT_PACKAGES)


def test_tasks_import_a_robot_package_only_in_its_config():
    """In ``tasks/``, a robot's facts are read only by that robot's task config (``config/<robot>/``, e.g.
    ``tasks/common/config/g1/setup.py``); scenes, generic terms and task mdp modules stay robot-free."""
    bad = sorted(m for m in MODULES if _unit(m) == "tasks" and _imports_robot_package(m) and ".config." not in m)
    assert not bad, "task modules outside config/<robot>/ importing a robot package:\n" + "\n".join(bad)


def test_robot_packages_are_imported_only_by_robots_and_tasks():
    bad = sorted(
        m
        for m in MODULES
        if _unit(m) not in ("robots", "tasks") and _imports_robot_package(m) and m not in ROBOT_IMPORT_ALLOWED
    )
    assert not bad, (
        "modules importing a robot package directly (read the robot through env.robot / "
        "robots.registry.robot_binding):\n" + "\n".join(bad)
    )
    stale = sorted(m for m in ROBOT_IMPORT_ALLOWED if m not in MODULES or not _imports_robot_package(m))
    assert not stale, f"ROBOT_IMPORT_ALLOWED entries that no longer import a robot package (remove them): {stale}"


# ----------------------------------------------------------------------------- environment variables
LIBRARY = ("newton_lab", "kernels", "tasks", "flows")
ENV_DOC = ROOT / "docs" / "installation.md"


def _documented_variables() -> set[str]:
    """The variables of the table under "## Environment variables" in docs/installation.md (``PREFECT_*``: a prefix)."""
    text = ENV_DOC.read_text().split("## Environment variables", 1)[1].split("\n## ", 1)[0]
    return {
        name
        for row in text.splitlines()
        if row.startswith("| `")
        for name in re.findall(r"`([A-Z][A-Z0-9_]*\*?)`", row.split("|")[1])
    }


def _is_environ(node: ast.AST) -> bool:
    return (
        isinstance(node, ast.Attribute)
        and node.attr == "environ"
        and isinstance(node.value, ast.Name)
        and node.value.id == "os"
    )


def _environment_reads(trees: dict[str, ast.Module]) -> dict[str, list[str]]:
    """Variable -> ``file:line`` of each read (``os.environ[K]``, ``.get(K)``, ``K in os.environ``, ``os.getenv(K)``)
    in ``trees``; a key that is no string constant (or module-level name of one) reads as ``<unresolved>``, any other
    use of ``os.environ`` than a read, a write or passing the whole environment on as ``<other use>``."""
    reads: dict[str, list[str]] = defaultdict(list)
    for rel, tree in trees.items():
        consts = {
            t.id: n.value.value
            for n in tree.body
            if isinstance(n, ast.Assign) and isinstance(n.value, ast.Constant) and isinstance(n.value.value, str)
            for t in n.targets
            if isinstance(t, ast.Name)
        }
        parents = {child: parent for parent in ast.walk(tree) for child in ast.iter_child_nodes(parent)}

        def key(node: ast.AST, consts: dict[str, str] = consts) -> str:
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                return node.value
            return consts.get(node.id, "<unresolved>") if isinstance(node, ast.Name) else "<unresolved>"

        for node in ast.walk(tree):
            where = f"{rel}:{getattr(node, 'lineno', 0)}"
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr == "getenv"
                and isinstance(node.func.value, ast.Name)
                and node.func.value.id == "os"
            ):
                reads[key(node.args[0]) if node.args else "<unresolved>"].append(where)
            if not _is_environ(node):
                continue
            up = parents.get(node)
            if isinstance(up, ast.Subscript) and isinstance(up.ctx, ast.Load):
                reads[key(up.slice)].append(where)
            elif isinstance(up, ast.Subscript):
                continue  # a write: a default for a library this process starts
            elif isinstance(up, ast.Attribute) and up.attr == "get" and isinstance(parents.get(up), ast.Call):
                call = parents[up]
                reads[key(call.args[0]) if call.args else "<unresolved>"].append(where)
            elif isinstance(up, ast.Attribute) and up.attr in ("setdefault", "copy"):
                continue  # a default set for a library, or the whole environment handed to a child
            elif isinstance(up, ast.Compare) and up.comparators == [node]:
                reads[key(up.left)].append(where)
            elif isinstance(up, ast.Dict) or (
                isinstance(up, ast.Call) and isinstance(up.func, ast.Name) and up.func.id == "dict"
            ):
                continue  # ``{**os.environ, ...}``: the whole environment handed to a child process
            else:
                reads["<other use>"].append(where)
    return dict(reads)


def _undocumented(reads: dict[str, list[str]], documented: set[str]) -> list[str]:
    prefixes = tuple(d[:-1] for d in documented if d.endswith("*"))
    return sorted(
        f"{name} at {', '.join(where)}"
        for name, where in reads.items()
        if name not in documented and not (prefixes and name.startswith(prefixes))
    )


def test_the_library_reads_only_the_documented_environment_variables():
    """Library code reads no environment variable the user guide does not list: tuning knobs are typed settings
    passed down, and tests arm their faults through seams they own, not through the environment."""
    documented = _documented_variables()
    assert {"NEWTON_LAB_VERBOSE", "NEWTON_LAB_WARP_BACKWARD", "NEWTON_LAB_COMMAND", "NEWTON_LAB_COMMIT"} <= documented
    bad = _undocumented(_environment_reads(_source_files(LIBRARY)), documented)
    assert not bad, f"environment variables read by the library but not documented in {ENV_DOC.name}:\n" + "\n".join(
        bad
    )


ENV_READS = """
import os
FLAG = "NEWTON_LAB_FLAG"
os.environ.get(FLAG)
os.environ["NEWTON_LAB_X"]
"NEWTON_LAB_TEST_FAULT" in os.environ
os.getenv("PREFECT_HOME")
os.environ.get(name)
os.environ.setdefault("SVT_LOG", "1")
os.environ["PREFECT_HOME"] = "x"
env = {**os.environ, "PYTHONPATH": "p"}
for k in os.environ: pass
"""


def test_the_environment_rule_catches_what_it_names():
    reads = _environment_reads({"newton_lab/x.py": ast.parse(ENV_READS)})
    assert sorted(reads) == sorted(
        ["NEWTON_LAB_FLAG", "NEWTON_LAB_X", "NEWTON_LAB_TEST_FAULT", "PREFECT_HOME", "<unresolved>", "<other use>"]
    )
    assert [b.split(" at ")[0] for b in _undocumented(reads, {"PREFECT_*", "NEWTON_LAB_X"})] == [
        "<other use>",
        "<unresolved>",
        "NEWTON_LAB_FLAG",
        "NEWTON_LAB_TEST_FAULT",
    ]


def test_the_datasets_package_keeps_its_top_level_small():
    """``newton_lab/datasets/`` holds its public API at the top and the rest in rooms (hdf5/, zarr/, files/,
    writers/, lerobot/, yolo/)."""
    top = sorted(p.name for p in (ROOT / "newton_lab" / "datasets").glob("*.py"))
    assert len(top) <= 8, f"newton_lab/datasets/ has {len(top)} modules at its top level (at most 8): {top}"
