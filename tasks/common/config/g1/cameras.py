"""Camera sets the G1 tasks declare (as on the reference platform): the front head camera at 298 x 224."""

from __future__ import annotations

from newton_lab.task_api.cfg import CameraCfg


def front_head_rgb() -> dict[str, CameraCfg]:
    """PickCube, PickCube-Mimic and the PickToShelf family: ``front_head`` RGB 298 x 224."""
    return {"front_head": CameraCfg(width=298, height=224, data=("rgb",))}


def front_head_rgb_depth_segmentation() -> dict[str, CameraCfg]:
    """The SortToShelf family (reference mode ``rgbd_semantic``): ``front_head`` RGB + depth + segmentation."""
    return {"front_head": CameraCfg(width=298, height=224, data=("rgb", "depth", "segmentation"))}


def teleop_rgb() -> dict[str, CameraCfg]:
    """PickCube-Teleop: the operator's views, ``left_wrist`` and ``front_head`` RGB at 640 x 480."""
    return {
        "left_wrist": CameraCfg(width=640, height=480, data=("rgb",)),
        "front_head": CameraCfg(width=640, height=480, data=("rgb",)),
    }
