"""No path read from a file (a LeRobot info.json template, a pipeline manifest, a scenario) is used outside the
folder that file describes: a crafted file gets a one-line error and nothing outside is read, replaced or deleted."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from newton_lab.datasets import open_writer
from newton_lab.datasets.files.inside_root import OutsidePathError, contained
from newton_lab.datasets.lerobot import export_lerobot, validate_lerobot_v3

TASK = "GalbotG1-PickCube-v0"
ENV_ARGS = {
    "env_kwargs": {"num_envs": 1, "seed": 0},
    "newton_lab": {
        "sim_dt": 0.01,
        "decimation": 5,
        "action_joint_names": [f"j{i}" for i in range(8)],
        "obs_terms": {"tcp_pose": [0, 7], "actions": [7, 15]},
    },
}


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture: these tests never import Warp."""
    yield


def test_contained_accepts_inside_and_refuses_escapes(tmp_path):
    root = tmp_path / "root"
    (root / "data").mkdir(parents=True)
    assert contained(root, "data/x.parquet", "f") == (root / "data/x.parquet").resolve()
    assert contained(root, root / "data", "f") == (root / "data").resolve()
    (tmp_path / "secret").write_text("outside")
    os.symlink(tmp_path / "secret", root / "data" / "link")
    for rel in ("../secret", "data/../../secret", str(tmp_path / "secret"), "data/link", "/etc/hostname"):
        with pytest.raises(OutsidePathError) as exc:
            contained(root, rel, "meta/info.json data_path")
        msg = str(exc.value)
        assert "\n" not in msg and "outside" in msg and "meta/info.json data_path" in msg, msg


def _dataset(path: Path) -> Path:
    rng = np.random.default_rng(0)
    with open_writer(path, task_id=TASK, env_args=ENV_ARGS, fsync=False) as w:
        for steps in (6, 5):
            actions = rng.standard_normal((steps, 8)).astype(np.float32)
            w.append_episode(
                {
                    "actions": actions,
                    "obs": {"tcp_pose": rng.standard_normal((steps, 7)).astype(np.float32), "actions": actions.copy()},
                },
                success=True,
                attrs={"termination_reason": "success"},
            )
    return path


@pytest.mark.parametrize(
    "key, template",
    [
        ("data_path", "data/../../outside/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"),
        ("data_path", "/tmp/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"),
    ],
)
def test_lerobot_info_templates_stay_inside_the_root(tmp_path, key, template):
    root = tmp_path / "export"
    export_lerobot(_dataset(tmp_path / "src.hdf5"), root)
    validate_lerobot_v3(root)
    info_path = root / "meta/info.json"
    info = json.loads(info_path.read_text())
    info[key] = template
    info_path.write_text(json.dumps(info))
    with pytest.raises(ValueError) as exc:
        validate_lerobot_v3(root)
    msg = str(exc.value)
    assert "\n" not in msg and "points outside" in msg and key in msg, msg


def test_pipeline_manifest_pointing_outside_is_refused(tmp_path):
    from newton_lab.flows import stages  # deferred: Prefect-free module, but the flows package is heavy to import

    out = tmp_path / "out"
    out.mkdir()
    victim = tmp_path / "precious.hdf5"
    victim.write_bytes(b"user data")
    inputs = {"stage": "collect", "task_id": TASK}
    (out / "demos.manifest.json").write_text(json.dumps({"inputs": inputs, "artifact": {"path": str(victim)}}))
    with pytest.raises(OutsidePathError, match="points outside"):
        stages._guard(out, "demos", inputs)
    assert victim.read_bytes() == b"user data"


def test_scenario_files_carry_no_paths(tmp_path):
    from newton_lab.envs.scenario import ScenarioError, load_scenario  # deferred: imports Warp

    bad = tmp_path / "scn.yaml"
    bad.write_text("schema: 1\nframe: env\ninclude: /etc/hostname\n")
    with pytest.raises(ScenarioError) as exc:
        load_scenario(bad)
    assert "\n" not in str(exc.value) and "include" in str(exc.value)
