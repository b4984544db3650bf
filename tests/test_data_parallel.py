"""Data-parallel training on the CPU: two gloo processes under torchrun, each on half of every global batch, end
where one process ends on the whole batch (same windows, same diffusion noise, averaged gradients), and the
checkpoint has the single-process format. Real training of a tiny policy through ``train(..., gpus=2)``."""

from __future__ import annotations

import json

import pytest
import torch
from test_policy import TINY, write_dataset

from newton_lab.cli.parsing import parse_args
from newton_lab.commands import TrainArgs
from newton_lab.policies import DiffusionPolicy, train

CFG = dict(TINY, lr=1e-2, warmup_steps=2, epochs=100, max_steps=4, seed=0)
"""40 windows; 4 steps of a 16-window global batch (two epochs of 2 steps)."""


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture: these tests train only."""
    yield


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return write_dataset(tmp_path_factory.mktemp("ddp_data") / "demos.hdf5")


@pytest.fixture(scope="module")
def one_process(dataset, tmp_path_factory):
    """The reference: one process, batch 16."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return train(dataset, {**CFG, "batch_size": 16, "output_dir": str(tmp_path_factory.mktemp("one"))})
    finally:
        torch.set_num_threads(threads)


def test_two_gloo_processes_take_the_steps_of_one(dataset, one_process, tmp_path, monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    out = tmp_path / "two"
    path = train(dataset, {**CFG, "batch_size": 8, "output_dir": str(out)}, gpus=2)
    assert path == out / "checkpoint.pt"
    assert sorted(p.name for p in out.iterdir()) == ["checkpoint.pt", "train_log.json"]  # rank 0 wrote, no leftovers
    got, want = torch.load(path, weights_only=True), torch.load(one_process, weights_only=True)
    assert got.keys() == want.keys() and got["weights"].keys() == want["weights"].keys()
    assert got["info"]["training"]["steps"] == want["info"]["training"]["steps"] == 4
    # Float sums in another order: equal to rounding, except where Adam divides by a near-zero second moment
    # and turns a rounding difference into a visible one (a few elements in thousands). Without the gradient
    # average, or with per-rank noise, every tensor moves by about the learning rate.
    for key, want_w in want["weights"].items():
        off = (got["weights"][key] - want_w).norm().item()
        assert off <= 1e-3 * want_w.norm().item() + 1e-6, f"{key}: off by {off:.2e} (norm {want_w.norm():.2e})"
    log = json.loads((out / "train_log.json").read_text())
    assert log["steps"] == 4 and log["batch_size"] == 8
    DiffusionPolicy.load(path)  # loads as any checkpoint


def test_train_command_takes_gpus(dataset):
    args = parse_args(TrainArgs, ["--dataset-path", str(dataset), "--gpus", "2"])
    assert args.gpus == 2


def test_more_gpus_than_the_host_has_is_one_line(dataset, tmp_path):
    with pytest.raises(ValueError, match=r"--gpus 64 needs 64 GPUs, this host shows \d+"):
        train(dataset, {**CFG, "device": "cuda", "output_dir": str(tmp_path / "p")}, gpus=64)
    assert not (tmp_path / "p").exists()
