"""A collected dataset in robomimic's layout: the keys robomimic's ``SequenceDataset`` reads, checked with h5py
directly, then loaded by robomimic 0.3.0 itself where it is installed (``pip install -e '.[robomimic]'``)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from conftest import missing_tool

from newton_lab.agents import PlannerAgent, ZeroAgent
from newton_lab.cli import main
from newton_lab.datasets import read_dataset_info, read_episode, read_filter_keys, split_train_val, state_tree
from newton_lab.datasets.merge import merge_datasets

DATASET_KEYS = ("actions", "rewards", "dones", "states")


@pytest.fixture(scope="module")
def collected(pick_env, tmp_path_factory):
    """Two expert episodes (successes) and two 4-step zero-action ones (failures), split by the CLI."""
    path = tmp_path_factory.mktemp("robomimic") / "demos.hdf5"
    pick_env.collect(
        agent=PlannerAgent.from_task(pick_env.task_id), episodes=2, path=path, max_steps=400, progress=False
    )
    pick_env.collect(agent=ZeroAgent(), episodes=2, path=path, max_steps=4, progress=False)
    return path


def test_cli_split_writes_robomimic_filter_keys(collected, capsys):
    assert main(["split", "--dataset-path", str(collected), "--val-ratio", "0.5"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["filter_keys"] == {"successful": 2, "train": 2, "valid": 2}
    with h5py.File(collected, "r") as f:  # what robomimic's get_demos_for_filter_key reads
        train = [n.decode() for n in f["mask/train"][()]]
        valid = [n.decode() for n in f["mask/valid"][()]]
        assert f["mask/train"].dtype.kind == "S" and sorted(train + valid) == sorted(f["data"].keys())
        assert [n.decode() for n in f["mask/successful"][()]] == ["demo_0", "demo_1"]
    assert read_filter_keys(collected)["train"] == sorted(train, key=lambda n: int(n[5:]))


def test_demos_hold_what_robomimic_reads(collected):
    info = read_dataset_info(collected)
    layout = info["env_args"]["newton_lab"]["state_layout"]
    with h5py.File(collected, "r") as f:
        assert json.loads(f["data"].attrs["env_args"])["type"] == 2  # robomimic's EnvType.GYM_TYPE
        for name, demo in f["data"].items():
            t = int(demo.attrs["num_samples"])
            success = bool(demo.attrs["success"])
            assert demo["actions"].shape == (t, 8) and demo["actions"].dtype == np.float32
            assert demo["rewards"].shape == (t,) and demo["rewards"].dtype == np.float32
            assert demo["dones"][()].tolist() == [0] * (t - 1) + [int(success)], name
            assert demo["states"].shape == (t, layout["joint_qd"][1]) and demo["states"].dtype == np.float32
            assert all(demo[f"obs/{k}"].shape[0] == t for k in demo["obs"])
            assert sorted(demo["next_obs"]) == sorted(demo["obs"])
            assert all(demo[f"next_obs/{k}"].shape == demo[f"obs/{k}"].shape for k in demo["obs"])
            assert info["demos"][int(name[5:])]["success"] == success
    ep = read_episode(collected, 0)
    states = state_tree(ep["states"], info["env_args"])
    # the flat state holds the cube the observation saw
    np.testing.assert_allclose(states["rigid_object"]["cube"]["root_pose"], ep["obs"]["cube_pose"], atol=1e-6)
    assert np.isfinite(ep["rewards"]).all()


def test_zarr_holds_the_same_keys(collected, tmp_path):
    zpath = merge_datasets([collected], tmp_path / "demos.zarr").path
    assert split_train_val(zpath, 0.5) == split_train_val(collected, 0.5) == read_filter_keys(zpath)
    for demo in (0, 3):
        h, z = read_episode(collected, demo), read_episode(zpath, demo)
        for key in DATASET_KEYS:
            np.testing.assert_array_equal(z[key], h[key])
        assert sorted(z["obs"]) == sorted(h["obs"])


def test_robomimic_sequence_dataset_loads_it(collected):
    try:
        import robomimic.utils.obs_utils as obs_utils
        from robomimic.utils.dataset import SequenceDataset
    except ImportError as e:
        missing_tool(f"robomimic is not installed ({e}); pip install -e '.[robomimic]' to run this check")
    import torch

    assert main(["split", "--dataset-path", str(collected), "--val-ratio", "0.5"]) == 0
    obs_keys = sorted(read_episode(collected, 0)["obs"])
    obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": obs_keys, "rgb": []}})
    train = [int(n[5:]) for n in read_filter_keys(collected)["train"]]
    for cache in ("low_dim", None):  # robomimic's default cache mode, and reads straight from the file
        ds = SequenceDataset(
            hdf5_path=str(collected),
            obs_keys=obs_keys,
            dataset_keys=DATASET_KEYS,
            seq_length=4,
            frame_stack=1,
            hdf5_cache_mode=cache,
            filter_by_attribute="train",
            goal_mode="last",
        )  # load_next_obs=True (its default): the goal is the last next_obs
        eps = {d: read_episode(collected, d) for d in train}
        assert ds.n_demos == len(train) and len(ds) == sum(e["attrs"]["num_samples"] for e in eps.values())
        first = eps[train[0]]
        item = ds[0]
        np.testing.assert_array_equal(item["actions"], first["actions"][:4])
        np.testing.assert_array_equal(item["rewards"], first["rewards"][:4])
        np.testing.assert_array_equal(item["states"], first["states"][:4])
        for k in obs_keys:
            np.testing.assert_array_equal(item["obs"][k], first["obs"][k][:4])
            np.testing.assert_array_equal(item["next_obs"][k], first["next_obs"][k][:4])
            np.testing.assert_array_equal(item["goal_obs"][k], first["next_obs"][k][-1])
        last = ds[len(ds) - 1]  # padded at the end of the last demo, as robomimic pads
        final = eps[train[-1]]
        assert last["dones"][-1] == final["dones"][-1] == int(final["attrs"]["success"])
        batch = next(iter(torch.utils.data.DataLoader(ds, batch_size=3)))
        assert tuple(batch["actions"].shape) == (3, 4, 8) and tuple(batch["rewards"].shape) == (3, 4)
        ds.close_and_delete_hdf5_handle()
