"""The visuomotor diffusion policy at 96x72 on CPU: the ResNet-18/GroupNorm + spatial-softmax encoder, image
windows from a real image dataset, shape / key mismatch errors, the checkpoint round trip and the camera checks of
``PolicyAgent``."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from newton_lab.policies.diffusion import PRESETS, DiffusionPolicy, DiffusionPolicyConfig
from newton_lab.policies.vision import ImageEncoder, SpatialSoftmax, crop_frames

CAMERAS = {"front_head": (96, 72)}
PROPRIO = ("robot_joint_pos", "gripper_pos")


def test_spatial_softmax_finds_the_hot_pixel():
    pool = SpatialSoftmax(1, keypoints=1)
    with torch.no_grad():
        pool.keypoints.weight.fill_(1.0)
        pool.keypoints.bias.zero_()
    x = torch.zeros(1, 1, 9, 17)
    x[0, 0, 2, 12] = 50.0
    xy = pool(x)[0]
    assert xy.tolist() == pytest.approx([12 / 16 * 2 - 1, 2 / 8 * 2 - 1], abs=1e-3)


def test_crops_stay_inside_and_centre_at_inference():
    x = torch.arange(2 * 10 * 12 * 3, dtype=torch.int32).reshape(2, 10, 12, 3).to(torch.uint8)
    c = crop_frames(x, (8, 10), random=False)
    assert torch.equal(c, x[:, 1:9, 1:11])
    for _ in range(20):
        r = crop_frames(x, (8, 10), random=True)
        assert r.shape == (2, 8, 10, 3)
        for n in range(2):  # every crop is a window of its own frame
            hits = [(i, j) for i in range(3) for j in range(3) if torch.equal(r[n], x[n, i : i + 8, j : j + 10])]
            assert hits


def test_encoder_shapes_and_errors():
    enc = ImageEncoder({"front_head_rgb": (72, 96, 3)}, crop=0.9, feature_dim=8, width=16)
    frames = torch.randint(0, 255, (3, 2, 72, 96, 3), dtype=torch.uint8)
    assert enc({"front_head_rgb": frames}).shape == (3, 2, 8)
    with pytest.raises(ValueError, match=r"images \['front_head_rgb'\] are missing"):
        enc.check({"left_wrist_rgb": frames})
    with pytest.raises(ValueError, match=r"frames are \(224, 298, 3\), the policy was trained on \(72, 96, 3\)"):
        enc.check({"front_head_rgb": torch.zeros(1, 2, 224, 298, 3, dtype=torch.uint8)})


# ---------------------------------------------------------------- on a real image dataset (CPU physics)
@pytest.fixture(scope="module")
def image_demos(tmp_path_factory):
    """Two PickCube expert demos with the front-head camera at 96x72 (seed 0, randomised)."""
    from newton_lab.agents import PlannerAgent
    from newton_lab.envs import make_env

    env = make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=0, randomize=True, cameras=CAMERAS)
    path = tmp_path_factory.mktemp("vision") / "demos.hdf5"
    ref = env.collect(agent=PlannerAgent.from_task(env.task_id), episodes=2, path=path, progress=False)
    assert ref["successes"] == 2
    return path


def _cfg(tmp_path, **kw) -> DiffusionPolicyConfig:
    preset = {**PRESETS["vision_cpu"], "max_steps": 2, "batch_size": 4}
    return DiffusionPolicyConfig(
        **{
            **preset,
            "output_dir": str(tmp_path / "policy"),
            "progress": False,
            "checkpoint_every_steps": None,
            "checkpoint_every_s": None,
            **kw,
        }
    )


def test_image_windows_and_checkpoint_round_trip(image_demos, tmp_path):
    from newton_lab.policies import Policy
    from newton_lab.policies.data import SequenceDataset

    data = SequenceDataset(image_demos, obs_keys=PROPRIO, image_keys=("front_head_rgb",))
    batch = data.__getitems__([0, 5, 7])
    assert batch["images"]["front_head_rgb"].shape == (3, 2, 72, 96, 3)
    assert batch["images"]["front_head_rgb"].dtype == torch.uint8 and batch["obs"].shape[:2] == (3, 2)
    with pytest.raises(ValueError, match="has no image obs/left_wrist_rgb; image terms there: front_head_rgb"):
        SequenceDataset(image_demos, obs_keys=PROPRIO, image_keys=("left_wrist_rgb",))

    path = Policy.from_backend("diffusion").train(image_demos, _cfg(tmp_path))
    policy = DiffusionPolicy.load(path)
    assert policy.info["image_keys"] == ["front_head_rgb"] and policy.info["image_shapes"] == {
        "front_head_rgb": [72, 96, 3]
    }
    assert policy.obs_keys == list(PROPRIO) and policy.cfg.crop == 0.9
    again = DiffusionPolicy.load(path)
    obs, images = batch["obs"][:1], {"front_head_rgb": batch["images"]["front_head_rgb"][:1]}
    a = policy.predict_action(obs, images=images, generator=torch.Generator().manual_seed(0))
    b = again.predict_action(obs, images=images, generator=torch.Generator().manual_seed(0))
    assert torch.equal(a, b)
    with pytest.raises(ValueError, match="this policy sees images"):
        policy.predict_action(obs)


def test_bf16_training_keeps_float32_weights(image_demos, tmp_path):
    from newton_lab.policies import Policy

    path = Policy.from_backend("diffusion").train(image_demos, _cfg(tmp_path, bf16=True))
    ckpt = torch.load(path, weights_only=True)
    assert ckpt["config"]["bf16"] is True
    assert {v.dtype for v in ckpt["weights"].values() if v.is_floating_point()} == {torch.float32}
    assert torch.isfinite(
        torch.tensor(__import__("json").loads((path.parent / "train_log.json").read_text())["final_loss"])
    )


def test_the_device_resident_windows_give_the_host_loaders_batches(image_demos):
    """The captured step's data path (every window's arrays copied to its device once, frames kept uint8, batches
    gathered there by ``Windows.batch``) and the eager step's DataLoader over the dataset give the same batch for the
    same windows: the first batch of the eager step's seeded order, gathered both ways."""
    from newton_lab.datasets import read_episode
    from newton_lab.policies.data import SequenceDataset
    from newton_lab.policies.train_step import EagerTrainStep

    cfg = DiffusionPolicyConfig(**{**PRESETS["vision_cpu"], "batch_size": 8, "seed": 3})
    data = SequenceDataset(image_demos, obs_keys=cfg.obs_keys, image_keys=cfg.image_keys, obs_horizon=2)
    policy = DiffusionPolicy.from_dataset(data, cfg)
    step = EagerTrainStep(policy, data, cfg)
    step.generator.manual_seed(cfg.seed)
    indices = next(iter(step.loader.batch_sampler))
    step.generator.manual_seed(cfg.seed)  # the same order again, through the loader
    host = next(iter(step.loader))
    device = data.windows("cpu").batch(torch.as_tensor(indices))  # the GPU path's gather, here on the CPU
    assert torch.equal(device["obs"], host["obs"]) and torch.equal(device["actions"], host["actions"])
    assert device["obs"].shape == (8, 2, data.obs_dim)
    for key, frames in host["images"].items():
        assert device["images"][key].dtype == torch.uint8 and torch.equal(device["images"][key], frames), key
    # and both are the recorded frames of those windows, read from the file on their own
    recorded = np.concatenate([read_episode(file, demo)["obs"]["front_head_rgb"] for file, demo in data.demos])
    window_frames = data.obs_index[torch.as_tensor(indices)].numpy()
    assert np.array_equal(host["images"]["front_head_rgb"].numpy(), recorded[window_frames])


NORM_SHAPES = [((5, 32, 9, 7), 4), ((3, 64, 43, 33), 4), ((4, 512, 3, 2), 32), ((6, 64, 16), 4)]
"""(input shape, groups): an encoder's stem and last stage, and a U-Net's 1-D norm."""


@pytest.mark.parametrize("shape,groups", NORM_SHAPES)
def test_group_norm_by_rows_is_group_norm_with_its_gradients(shape, groups):
    """The CUDA path of the policies' bf16 GroupNorm (layer-norm kernels over each sample's groups, then the
    per-channel affine) is ``F.group_norm``: the same values and the same gradients of input, weight and bias
    (float64, to rounding), for the encoders' and the U-Net's shapes."""
    from newton_lab.policies.norm import group_norm_by_rows

    torch.manual_seed(0)
    x = torch.randn(*shape, dtype=torch.float64, requires_grad=True)
    w = torch.randn(shape[1], dtype=torch.float64, requires_grad=True)
    b = torch.randn(shape[1], dtype=torch.float64, requires_grad=True)
    native, rows = F.group_norm(x, groups, w, b, 1e-5), group_norm_by_rows(x, groups, w, b, 1e-5)
    assert torch.allclose(rows, native, atol=1e-12)
    upstream = torch.randn_like(native)
    for a, r in zip(torch.autograd.grad(native, (x, w, b), upstream), torch.autograd.grad(rows, (x, w, b), upstream)):
        assert torch.allclose(r, a, atol=1e-10)
    assert torch.allclose(group_norm_by_rows(x, groups, None, None, 1e-5), F.group_norm(x, groups, eps=1e-5))


def test_bf16_norms_run_the_group_norms_in_the_autocast_dtype_with_the_same_weights(image_demos, tmp_path):
    """``bf16_norms``: under autocast each GroupNorm computes in bfloat16 (a float32 input comes out bfloat16, as
    close to the float32 norm as bf16 rounding allows; off, it stays float32 as ``nn.GroupNorm`` does); outside
    autocast nothing changes. A policy trained that way keeps the norms' switch in its config, float32 weights
    and the state dict's keys."""
    from newton_lab.policies import Policy
    from newton_lab.policies.diffusion import DiffusionPolicy
    from newton_lab.policies.norm import GroupNorm, set_low_precision_norms

    norm, x = GroupNorm(4, 32), torch.randn(3, 32, 9, 7)
    ref = norm(x)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        assert norm(x).dtype == torch.float32
        set_low_precision_norms(norm, True)
        low = norm(x)
    assert low.dtype == torch.bfloat16
    torch.testing.assert_close(low.float(), ref, atol=0.05, rtol=0.02)
    torch.testing.assert_close(norm(x), ref)  # no autocast: float32 as before

    path = Policy.from_backend("diffusion").train(image_demos, _cfg(tmp_path, bf16=True, bf16_norms=True))
    ckpt = torch.load(path, weights_only=True)
    assert ckpt["config"]["bf16_norms"] is True
    assert {v.dtype for v in ckpt["weights"].values() if v.is_floating_point()} == {torch.float32}
    policy = DiffusionPolicy.load(path)
    norms = [m for m in policy.model.modules() if isinstance(m, GroupNorm)]
    assert norms and all(m.low_precision for m in norms)
    plain = DiffusionPolicy.load(Policy.from_backend("diffusion").train(image_demos, _cfg(tmp_path / "plain")))
    assert plain.model.state_dict().keys() == policy.model.state_dict().keys()


def test_policy_agent_refuses_other_cameras(image_demos, tmp_path):
    from newton_lab.envs import make_env
    from newton_lab.policies import Policy
    from newton_lab.policies.agent import PolicyAgent

    path = Policy.from_backend("diffusion").train(image_demos, _cfg(tmp_path))
    for cameras, match in (
        (False, "does not render"),
        ({"front_head": (128, 96)}, r"cameras=\{'front_head': \(96, 72\)\}"),
    ):
        env = make_env("GalbotG1-PickCube-v0", num_envs=1, device="cpu", cameras=cameras)
        with pytest.raises(ValueError, match=match):
            PolicyAgent.from_checkpoint(path).act(env)


@pytest.mark.slow
def test_image_policy_overfits_two_demos_and_replays_one(image_demos, tmp_path):
    """600 CPU steps on the two demos (96x72 frames plus proprioception and the last action, no crop
    augmentation), then the demos' own two episodes (the same env seed restarts their scenes) run closed loop
    from the camera: the policy places the cube on the block in at least one. The second training seed runs
    only if the first policy replays neither demo (the release over the block is the fragile step of a
    two-demo policy)."""
    import h5py
    import numpy as np

    from newton_lab.envs import make_env
    from newton_lab.policies import Policy
    from newton_lab.policies.agent import PolicyAgent

    with h5py.File(image_demos) as f:
        demo_cubes = np.stack([f[f"data/demo_{i}/datagen/object_poses/cube"][0, :3] for i in range(2)])
    for seed in (3, 0):
        cfg = _cfg(
            tmp_path / f"seed{seed}",
            max_steps=600,
            batch_size=16,
            lr=2e-3,
            warmup_steps=30,
            crop=1.0,
            seed=seed,
            obs_keys=(*PROPRIO, "actions"),
        )
        threads = torch.get_num_threads()
        torch.set_num_threads(1)  # one core: under two pytest workers, two threads only contend with the other
        try:
            path = Policy.from_backend("diffusion").train(image_demos, cfg)
        finally:
            torch.set_num_threads(threads)
        env = make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=0, randomize=True, cameras=CAMERAS)
        cube, first_cubes = env.sim.layout.entity_names.index("cube"), []

        def on_step(reward, info, env=env, cube=cube, first_cubes=first_cubes):
            if not first_cubes:
                first_cubes.append(env.buffers.entity_poses[:, cube, :3].cpu().numpy().copy())

        result = env.evaluate(
            agent=PolicyAgent.from_checkpoint(path), episodes=2, max_steps=300, progress=False, on_step=on_step
        )
        np.testing.assert_allclose(first_cubes[0], demo_cubes, atol=2e-3)  # the rows replay the demos' scenes
        assert result["subtask_signals"]["grasped_cube"] >= 1
        if result["successes"] >= 1:
            break
    assert result["successes"] >= 1, result


def test_bench_train_times_the_image_encoders_channels_last_to_the_same_loss(image_demos, tmp_path, capsys):
    """``bench-train --channels-last``: the convolutions in channels-last layout give the same training step (the
    layout moves numbers in memory, not their values)."""
    from newton_lab.cli import main

    argv = ["bench-train", "--dataset-path", str(image_demos), "--batch-size", "4", "--steps", "2"]
    assert main([*argv, "--preset", "vision_cpu", "--channels-last", "--run-record", str(tmp_path / "r.json")]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["image_keys"] and out["EagerTrainStep_cl_steps_per_s"] > 0
    assert out["EagerTrainStep_cl_final_loss"] == pytest.approx(out["EagerTrainStep_final_loss"], rel=1e-3)


def test_bench_train_profile_names_the_operators_that_spend_the_step(image_demos, capsys):
    """``bench-train --profile``: the eager step's operators by their own time per step, largest first, with their
    families; the image encoders' convolutions are among them. ``--bf16-norms`` adds its variant."""
    from newton_lab.bench_train import _family
    from newton_lab.cli import main

    argv = ["bench-train", "--dataset-path", str(image_demos), "--batch-size", "4", "--steps", "2"]
    assert main([*argv, "--preset", "vision_cpu", "--profile", "--bf16", "--bf16-norms", "--native-norms"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["EagerTrainStep_bf16norms_bf16_steps_per_s"] > 0  # the norms' variant beside plain bf16
    assert out["EagerTrainStep_nativenorms_bf16norms_bf16_steps_per_s"] > 0  # and on PyTorch's own norm kernels
    prof = out["profile"]
    top = [row["ms_per_step"] for row in prof["top"]]
    assert prof["clock"] == "cpu" and top == sorted(top, reverse=True) and top[0] > 0
    assert sum(prof["families_ms_per_step"].values()) == pytest.approx(prof["ms_per_step"], rel=1e-6)
    assert prof["families_ms_per_step"].get("convolution", 0) > 0
    assert [_family(op) for op in ("aten::cudnn_convolution", "aten::native_group_norm", "aten::addmm")] == [
        "convolution",
        "normalisation",
        "matmul",
    ]
    assert [_family(op) for op in ("aten::_to_copy", "aten::_fused_adamw_", "aten::mul")] == [
        "cast and copy",
        "optimiser",
        "elementwise and other",
    ]


def test_bench_train_takes_the_recipes_keys(image_demos, capsys):
    """``bench-train --obs-keys ... --image-keys ...`` times the network a recipe trains (its views and its
    proprioception), not the preset's."""
    from newton_lab.cli import main

    argv = ["bench-train", "--dataset-path", str(image_demos), "--batch-size", "4", "--steps", "2"]
    keys = ["--obs-keys", ",".join(PROPRIO), "--image-keys", "front_head_rgb"]
    assert main([*argv, "--preset", "vision_cpu", *keys]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["obs_keys"] == list(PROPRIO) and out["image_keys"] == ["front_head_rgb"]
    assert main([*argv, "--preset", "vision_cpu", "--cudnn-benchmark"]) == 0  # both sides of the autotuner's A/B
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["EagerTrainStep_steps_per_s"] > 0 and out["EagerTrainStep_tuned_steps_per_s"] > 0
    assert main([*argv, "--preset", "vision_cpu", "--image-keys", "left_wrist_rgb"]) == 2  # not in the dataset
    assert "left_wrist_rgb" in capsys.readouterr().err


def test_padded_sampling_gives_the_eager_actions(image_demos, tmp_path):
    """The graphed sampler's path (rows padded to a power-of-two bucket, copied into static inputs, the padding's
    actions dropped), run without graphs on the CPU, gives the actions ``predict_action`` gives for the same rows and
    seed; on a GPU the same inputs are replayed from one CUDA graph per bucket."""
    from newton_lab.policies import Policy
    from newton_lab.policies.data import SequenceDataset
    from newton_lab.policies.graphed import GraphedSampler, bucket

    assert [bucket(n, 100) for n in (1, 2, 3, 5, 64, 65, 100)] == [1, 2, 4, 8, 64, 100, 100]
    policy = DiffusionPolicy.load(Policy.from_backend("diffusion").train(image_demos, _cfg(tmp_path)))
    windows = SequenceDataset(image_demos, obs_keys=PROPRIO, image_keys=("front_head_rgb",)).__getitems__(
        [0, 3, 5, 7, 9]
    )
    sampler = GraphedSampler(policy, rows=8, static=True)
    assert not sampler.graphs  # no CUDA here: the static buffers, called eagerly
    for seed, rows in enumerate((slice(0, 3), slice(0, 1), slice(2, 5))):  # a bucket of 4 (built, then reused), of 1
        obs, images = windows["obs"][rows], {"front_head_rgb": windows["images"]["front_head_rgb"][rows]}
        eager = policy.predict_action(obs, images=images, generator=torch.Generator().manual_seed(seed))
        noise = policy.initial_noise(obs.shape[0], torch.Generator().manual_seed(seed))
        torch.testing.assert_close(sampler(obs, images, noise), eager, rtol=1e-4, atol=1e-5)
    assert sorted(sampler._buckets) == [1, 4]


def test_an_instruction_conditioned_policy_trains_saves_and_acts(image_demos, tmp_path):
    """``instruction_keys``: the named low-dim columns FiLM-condition the trunk (their maps trained off zero), the
    checkpoint keeps them, and the reloaded policy acts as the saved one does."""
    from newton_lab.policies import Policy
    from newton_lab.policies.data import SequenceDataset

    path = Policy.from_backend("diffusion").train(image_demos, _cfg(tmp_path, instruction_keys=("gripper_pos",)))
    policy = DiffusionPolicy.load(path)
    assert policy.cfg.instruction_keys == ("gripper_pos",)
    dims = policy.info["obs_dims"]
    start = dims["robot_joint_pos"]
    assert policy.instruction_spans == [(start, start + dims["gripper_pos"])], "gripper_pos follows the joints"
    film = {k: v for k, v in policy.ema.averaged.state_dict().items() if ".film." in k}
    assert film and any(v.abs().sum() > 0 for v in film.values()), "trained off their zero start"
    windows = SequenceDataset(image_demos, obs_keys=PROPRIO, image_keys=("front_head_rgb",)).__getitems__([0, 4])
    obs, images = windows["obs"], {"front_head_rgb": windows["images"]["front_head_rgb"]}
    again = DiffusionPolicy.load(path)
    a = policy.predict_action(obs, images=images, generator=torch.Generator().manual_seed(0))
    b = again.predict_action(obs, images=images, generator=torch.Generator().manual_seed(0))
    assert torch.equal(a, b)
    with pytest.raises(ValueError, match=r"instruction_keys \['sorting_object'\] are not observed"):
        DiffusionPolicy(
            DiffusionPolicyConfig(image_keys=("front_head_rgb",), instruction_keys=("sorting_object",)),
            obs_normalizer=policy.obs_normalizer,
            action_normalizer=policy.action_normalizer,
            info=policy.info,
        )
