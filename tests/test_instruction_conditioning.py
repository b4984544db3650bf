"""The image trunks conditioned on a task's instruction (FiLM, ``policies.vision``): a fresh conditioned trunk
computes what an unconditioned one does, a trained one answers the instruction, the settings refuse what cannot
work, and the long-horizon flow conditions a camera policy on its task's per-row target."""

from __future__ import annotations

import pytest
import torch

from newton_lab.policies.config import DiffusionPolicyConfig
from newton_lab.policies.vision import ImageEncoder

SHAPES = {"front_head_rgb": (72, 96, 3)}


def _one_hot(index: int, rows: int = 3, steps: int = 2) -> torch.Tensor:
    out = torch.zeros(rows, steps, 4)
    out[..., index] = 1.0
    return out


def test_a_fresh_conditioned_trunk_is_the_unconditioned_one():
    torch.manual_seed(0)
    plain = ImageEncoder(SHAPES, feature_dim=8, width=16).eval()
    told = ImageEncoder(SHAPES, feature_dim=8, width=16, instruction_dim=4).eval()
    missing, unexpected = told.load_state_dict(plain.state_dict(), strict=False)
    assert not unexpected and missing and all(".film." in k for k in missing), "only the FiLM maps are new"
    assert all(not p.any() for k, p in told.named_parameters() if ".film." in k), "FiLM maps start at zero"
    frames = {"front_head_rgb": torch.randint(0, 255, (3, 2, 72, 96, 3), dtype=torch.uint8)}
    with torch.no_grad():
        base = plain(frames)
        for i in range(4):
            torch.testing.assert_close(told(frames, _one_hot(i)), base, rtol=0, atol=0)
    with pytest.raises(ValueError, match="conditioned on a 4-wide instruction; pass it"):
        told(frames)


def test_a_trained_film_map_makes_the_features_follow_the_instruction():
    """One optimiser step on a loss that needs the instruction moves the zero-initialised maps off zero, and the
    same frames then give other features for another instruction."""
    torch.manual_seed(0)
    enc = ImageEncoder(SHAPES, feature_dim=8, width=16, instruction_dim=4)
    frames = {"front_head_rgb": torch.randint(0, 255, (4, 2, 72, 96, 3), dtype=torch.uint8)}
    instruction = torch.eye(4)[:, None, :].expand(4, 2, 4)
    target = torch.arange(4.0)[:, None, None].expand(4, 2, 8)  # a different answer per instruction
    optimiser = torch.optim.Adam(enc.parameters(), lr=1e-2)
    torch.nn.functional.mse_loss(enc(frames, instruction), target).backward()
    optimiser.step()
    film = [p for k, p in enc.named_parameters() if ".film." in k]
    assert film and all(p.abs().sum() > 0 for p in film)
    enc.eval()
    with torch.no_grad():
        one, other = enc(frames, instruction), enc(frames, instruction.roll(1, dims=0))
    assert (one - other).abs().max() > 1e-4


def test_instruction_settings_refuse_what_cannot_work():
    with pytest.raises(ValueError, match=r"instruction_keys \['sorting_object'\] condition the image trunks; give"):
        DiffusionPolicyConfig(instruction_keys=("sorting_object",))
    with pytest.raises(ValueError, match=r"must be among obs_keys \['robot_joint_pos'\]"):
        DiffusionPolicyConfig(
            image_keys=("front_head_rgb",), obs_keys=("robot_joint_pos",), instruction_keys="sorting_object"
        )
    cfg = DiffusionPolicyConfig(image_keys="front_head_rgb", instruction_keys="sorting_object")
    assert cfg.instruction_keys == ("sorting_object",) and "instruction_keys" in cfg.to_dict()


def test_the_flow_conditions_camera_policies_on_the_target_and_state_policies_not():
    from newton_lab.flows.settings import with_inputs

    camera = {"obs_keys": ["robot_joint_pos"], "image_keys": ["front_head_rgb"]}
    told = with_inputs(camera, ["sorting_object"])
    assert told["obs_keys"] == ["robot_joint_pos", "sorting_object"] and told["instruction_keys"] == ["sorting_object"]
    state = with_inputs({"obs_keys": ["robot_joint_pos"]}, ["sorting_object"])
    assert state == {"obs_keys": ["robot_joint_pos", "sorting_object"]}
    assert with_inputs(camera, []) == camera
