"""The env's cameras: a task's views on its robot's mounts, rendered by Newton's ``SensorCamera``.

All views of all worlds that share a resolution are rendered by one ``SensorCamera.update`` (views camera-major:
view ``k * N + w`` is camera ``k`` in world ``w``), after the view poses follow their mount bodies
(``kernels.camera.mount_transforms``) and the shape BVH is refit. That render is captured once as a graph and
launched only when images are read after a step or reset (``env.sensors.images[...]``, ``env.render()``): a step whose
images nobody reads renders nothing, and an env without cameras does no camera work at all (nothing is built).

Images are torch views of the Warp buffers: RGB uint8 (N, H, W, 3) (a view of the renderer's packed RGBA),
depth float32 (N, H, W) [m] along the view axis (inf where nothing is hit within 15 m), segmentation int32
(N, H, W) with ids named by ``segmentation_names``.

Vision randomisation (``randomize=True``, the env's reset randomisation): per row and episode, seeded (kernels
``shape_colors`` / ``mount_transforms`` key a counter-based RNG on (seed, row, ``episode_count[row]``), so a row's
look changes exactly when it resets and replays for the same seed): the objects' and table's colours (objects
named by their colour, ``EntityCfg.keep_hue``, keep it within +-20 % per channel), a brightness
gain on all of the row's shapes (the row's light intensity) and a camera-pose jitter (<= 1 cm, <= 1 deg) of each
view. Newton 1.8's ``SensorCamera`` has one light list for all worlds, so the light direction is not randomised
(per-row direction is not possible in one render); the ground is one global shape and keeps its colour.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass

import newton
import numpy as np
import torch
import warp as wp
from newton.sensors import SensorCamera

from ..kernels.camera import mount_transforms, segmentation_ids, shape_colors
from ..robots.binding import RobotBinding
from ..task_api.cfg import CameraCfg
from .camera_specs import ImageTerm, image_terms, resolve_cameras, segmentation_table
from .image_views import ImageViews
from .pictures import picture
from .render_settings import DEFAULT_LIGHT_DIRECTION, SKY_RGBA, build_render_bvh, render_config

__all__ = [
    "Cameras",
    "ImageTerm",
    "ImageViews",
    "ViewGroup",
    "image_terms",
    "picture",
    "resolve_cameras",
    "segmentation_table",
]


@dataclass
class ViewGroup:
    """The cameras of one resolution: one ``SensorCamera.update`` renders all their views in every world (views
    camera-major: view ``k * N + w`` is camera ``k`` in world ``w``)."""

    cameras: tuple[str, ...]
    width: int
    height: int
    rays: wp.array
    """(height, width, 1, 2) pinhole camera rays of the group's resolution (``SensorCamera.update``'s)."""
    view_body: wp.array
    """Mount body of each view (global body index)."""
    view_offset: wp.array
    """Camera pose in its mount body, per view."""
    world: wp.array
    """World of each view."""
    poses: wp.array
    """World pose of each view at the last render (``wp.transformf``)."""
    color: wp.array | None
    """Packed RGBA (uint32) per view and pixel; ``None`` when no camera of the group gives rgb."""
    depth: wp.array | None
    """Depth [m] per view and pixel; ``None`` without depth."""
    shape_index: wp.array | None
    """Shape hit per view and pixel; ``None`` without segmentation."""
    segmentation: wp.array | None
    """Segmentation id per view and pixel (``segmentation_names``); ``None`` without segmentation."""


class Cameras:
    """The cameras of one env. Built lazily: construction only checks and names; the first ``render`` allocates
    the ``SensorCamera``, the buffers and the captured render graph."""

    def __init__(
        self,
        specs: Mapping[str, CameraCfg],
        *,
        model: newton.Model,
        state: newton.State,
        num_envs: int,
        bodies_per_world: int,
        entity_names: list[str],
        capture: bool = True,
        randomize: bool = False,
        seed=lambda: 0,
        episode: wp.array | None = None,
        keep_hue: Collection[str] = (),
        hidden_groups: Collection[str] = (),
        robot: RobotBinding,
    ):
        self.robot = RobotBinding.required(robot, "Cameras")
        """The robot the cameras ride on (mounts, intrinsics, clipping, segmentation groups)."""
        self.specs = dict(specs)
        self.terms = image_terms(self.specs)
        self.model, self.state, self.num_envs = model, state, num_envs
        self.bodies_per_world = bodies_per_world
        self.entity_names = list(entity_names)
        self.keep_hue = frozenset(keep_hue)
        """Objects whose colour vision randomisation only jitters (``EntityCfg.keep_hue``)."""
        self.hidden_groups = tuple(hidden_groups)
        """Robot link groups the render leaves out (``RobotBinding.hidden_link_groups``: out of every view, so no
        pixel changes; ``hide`` changes them)."""
        self.capture = capture
        self.randomize = bool(randomize)
        """Vision randomisation on (switchable at any time; the render graph reads it from ``_params``)."""
        self._seed, self._episode = seed, episode if episode is not None else wp.zeros(num_envs, dtype=int)
        self._params, self._set = wp.zeros(2, dtype=int, device=model.device), (0, 0)
        self.stale = True
        """Set by every step / reset; the next read renders."""
        self._images: dict[str, torch.Tensor] | None = None
        self._groups: list[ViewGroup] = []
        self._names: tuple[str, ...] | None = None
        self._graph = None
        self.light: tuple[tuple[float, float, float], float] = (DEFAULT_LIGHT_DIRECTION, 1.0)
        """The scene's one directional light, for every row: (unit direction, world frame; intensity, the radiance
        of its white light); ``relight`` changes it."""

    def relight(self, direction, intensity: float = 1.0) -> None:
        """Set the directional light (``light``): ``direction`` a unit vector (world frame), ``intensity`` >= 0.
        Newton's renderer has one light list for all worlds, so it changes every row's pictures."""
        self.light = (tuple(float(c) for c in direction), float(intensity))
        if self.built:
            with wp.ScopedDevice(self.model.device):
                self._light()
        self.redraw()

    def redraw(self) -> None:
        """Record the captured render again: the renderer's arrays or settings changed (a light, a texture)."""
        if self.built:
            with wp.ScopedDevice(self.model.device):
                self._graph = self._capture() if self.capture else None
        self.stale = True

    def _light(self) -> None:
        (x, y, z), gain = self.light
        self.sensor.create_default_light(enable_shadows=False, direction=wp.vec3f(x, y, z), color=(gain, gain, gain))

    @property
    def segmentation_names(self) -> tuple[str, ...]:
        """Segmentation id -> name (``segmentation_table``)."""
        if self._names is None:
            self._names, self._shape_ids = segmentation_table(self.model, self.entity_names, self.robot)
        return self._names

    def id_colors(self) -> np.ndarray:
        """(N, ids, 3) float RGB in [0, 1] each segmentation id is drawn with in each row at the last render (its
        shapes' mean colour, after the vision randomisation); NaN for ids with no shape (background)."""
        self.render()
        colors = self.model.shape_color.numpy()[:, :3].astype(np.float64)
        world, ids = self.model.shape_world.numpy(), np.asarray(self._shape_ids)
        out = np.full((self.num_envs, len(self.segmentation_names), 3), np.nan)
        for i in np.unique(ids[ids > 0]):
            for row in range(self.num_envs):
                mine = (ids == i) & ((world == row) | (world < 0))
                if mine.any():
                    out[row, i] = colors[mine].mean(axis=0)
        return out

    def intrinsics(self, camera: str) -> np.ndarray:
        """3x3 pinhole matrix K [px] of ``camera`` at its resolution (u right, v down, centre principal point)."""
        c = self._spec(camera)
        return self.robot.camera_intrinsics(c.width, c.height)

    def poses(self, camera: str) -> torch.Tensor:
        """(N, 7) world pose (x, y, z, qx, qy, qz, qw) of ``camera`` at the last render (pinhole frame: looks along
        -z, +y up); renders first if the state moved since."""
        self.render()
        for g in self._groups:
            if camera in g.cameras:
                k = g.cameras.index(camera)
                return wp.to_torch(g.poses).view(-1, 7)[k * self.num_envs : (k + 1) * self.num_envs]
        raise KeyError(self._missing(camera))

    def _spec(self, camera: str) -> CameraCfg:
        if camera not in self.specs:
            raise KeyError(self._missing(camera))
        return self.specs[camera]

    def _missing(self, camera: str) -> str:
        if not self.specs:
            return f"camera {camera!r}: this env renders no cameras (a state-only task or cameras=False)"
        return f"camera {camera!r} is not rendered by this env; its cameras are {list(self.specs)}"

    @property
    def built(self) -> bool:
        """Whether the renderer, its buffers and its graph exist (the first ``render`` builds them; an env without
        cameras never does)."""
        return self._images is not None

    @property
    def view_groups(self) -> tuple[ViewGroup, ...]:
        """The views by resolution, with their Warp buffers (the image views share their memory); empty until
        built."""
        return tuple(self._groups)

    @property
    def render_graph(self):
        """The captured render (a Warp graph), ``None`` until built, with ``capture=False`` or where Warp cannot
        capture."""
        return self._graph

    @property
    def base_shape_colors(self) -> wp.array | None:
        """The model's shape colours before vision randomisation (``None`` until built); the render recolours
        ``model.shape_color`` from them."""
        return self._base_color if self.built else None

    # ------------------------------------------------------------------ build
    def _build(self) -> None:
        self.segmentation_names  # noqa: B018  (fills the shape -> id table)
        self._build_bvh()
        clear = SensorCamera.ClearData(clear_color=int.from_bytes(bytes(SKY_RGBA), "little"), clear_depth=math.inf)
        config = render_config(self.robot.camera_clipping[1])
        self.sensor = SensorCamera(
            self.model, default_clear_data=clear, default_render_config=config, load_textures=False
        )
        self._light()
        self._shape_to_id = wp.array(self._shape_ids, dtype=wp.int32)
        self._keep_hue = wp.array([int(n in self.keep_hue) for n in self.segmentation_names], dtype=wp.int32)
        self._base_color = wp.clone(self.model.shape_color)
        by_res: dict[tuple[int, int], list[str]] = {}
        for name, c in self.specs.items():
            by_res.setdefault((c.width, c.height), []).append(name)
        self._groups = [self._group(tuple(names), w, h) for (w, h), names in by_res.items()]
        self._images = self._views()

    def _build_bvh(self) -> None:
        hidden = [self.segmentation_names.index(g) for g in self.hidden_groups if g in self.segmentation_names]
        build_render_bvh(self.model, self.state, np.isin(self._shape_ids, hidden))

    def _group(self, names: tuple[str, ...], width: int, height: int) -> ViewGroup:
        n, v = self.num_envs, len(names) * self.num_envs
        body, offset = [], []
        for name in names:
            b, xf = self._mount(name)
            body += [b + w * self.bodies_per_world for w in range(n)]
            offset += [xf] * n
        wants = {d for name in names for d in self.specs[name].data}
        img = lambda dtype: wp.zeros((v, height, width), dtype=dtype)  # noqa: E731
        return ViewGroup(
            cameras=names,
            width=width,
            height=height,
            rays=wp.array(self.robot.camera_rays(width, height), dtype=wp.vec3f).reshape((height, width, 1, 2)),
            view_body=wp.array(body, dtype=int),
            view_offset=wp.array(offset, dtype=wp.transform),
            world=wp.array(np.tile(np.arange(n, dtype=np.int32), len(names)), dtype=wp.int32),
            poses=wp.zeros(v, dtype=wp.transformf),
            color=img(wp.uint32) if "rgb" in wants else None,
            depth=img(wp.float32) if "depth" in wants else None,
            shape_index=img(wp.uint32) if "segmentation" in wants else None,
            segmentation=img(wp.int32) if "segmentation" in wants else None,
        )

    def _mount(self, camera: str) -> tuple[int, wp.transform]:
        """(world-0 body index, camera offset in that body) of ``camera``'s MJCF site."""
        site = self.robot.camera_mounts[camera]
        world = self.model.shape_world.numpy()
        for s, label in enumerate(self.model.shape_label):
            if label.rsplit("/", 1)[-1] == site and world[s] == 0:
                xf = self.model.shape_transform.numpy()[s]
                return int(self.model.shape_body.numpy()[s]), wp.transform(wp.vec3(*xf[:3]), wp.quat(*xf[3:]))
        raise ValueError(f"the {self.robot.name} model has no camera site {site!r} for camera {camera!r}")

    def _views(self) -> dict[str, torch.Tensor]:
        out, n = {}, self.num_envs
        for g in self._groups:
            for k, cam in enumerate(g.cameras):
                rows = slice(k * n, (k + 1) * n)
                for term in (t for t in self.terms.values() if t.camera == cam):
                    if term.data == "rgb":
                        rgba = wp.to_torch(g.color).view(torch.uint8).view(-1, g.height, g.width, 4)
                        out[term.name] = rgba[rows, ..., :3]
                    elif term.data == "depth":
                        out[term.name] = wp.to_torch(g.depth)[rows]
                    else:
                        out[term.name] = wp.to_torch(g.segmentation)[rows]
        return {name: out[name] for name in self.terms}

    # ------------------------------------------------------------------ render
    def _render_body(self) -> None:
        wp.launch(
            shape_colors,
            dim=self.model.shape_count,
            inputs=[
                self._base_color,
                self.model.shape_world,
                self._shape_to_id,
                2 + len(self.entity_names),
                self._keep_hue,
                self._episode,
                self._params,
                self.model.shape_color,
            ],
        )
        first = 0
        for g in self._groups:
            wp.launch(
                mount_transforms,
                dim=g.poses.shape[0],
                inputs=[
                    self.state.body_q,
                    g.view_body,
                    g.view_offset,
                    g.world,
                    self._episode,
                    self._params,
                    first,
                    g.poses,
                ],
            )
            first += len(g.cameras)
        self.model.bvh_refit_shapes(self.state)
        for g in self._groups:
            self.sensor.update(
                self.state,
                g.poses,
                g.rays,
                color_image=g.color,
                forward_depth_image=g.depth,
                shape_index_image=g.shape_index,
                world_indices=g.world,
                sync_deformables=False,
            )
            if g.segmentation is not None:
                wp.launch(
                    segmentation_ids,
                    dim=g.segmentation.size,
                    inputs=[g.shape_index.flatten(), self._shape_to_id, g.segmentation.flatten()],
                )

    def render(self, *, force: bool = False, eager: bool = False) -> dict[str, torch.Tensor]:
        """Render every view if the state changed since the last render (``force``: anyway); returns the image
        views by term name. ``eager`` launches the render's kernels one by one instead of its captured graph
        (the same pictures)."""
        if not self.specs:
            return {}
        params = (int(self.randomize), int(self._seed()) & 0x7FFFFFFF)
        if params != self._set:  # written in place: the captured render reads it
            self._params.assign(np.array(params, dtype=np.int32))
            self._set, self.stale = params, True
        with wp.ScopedDevice(self.model.device):
            if self._images is None:
                self._build()
                self._render_body()  # compiles the render kernels before any capture
                self._graph = self._capture() if self.capture else None
            elif self.stale or force:
                if self._graph is not None and not eager:
                    wp.capture_launch(self._graph)
                else:
                    self._render_body()
        self.stale = False
        return self._images

    def use_render_order(self, order, block_dim: int, tile: tuple[int, int] | None = None) -> None:
        """Render from now on with this traversal order (``SensorCamera.RenderOrder``), thread-block size and tile
        (width, height) [px] of the tiled order: the same pictures at another speed (``bench --render-orders``
        times each). Builds the cameras if needed and captures the render again."""
        self.render()
        self.sensor.default_render_config = render_config(self.robot.camera_clipping[1], order, block_dim, tile)
        self._rerender()

    def hide(self, groups: Collection[str]) -> None:
        """Draw from now on every shape but those of these robot link groups (``()``: every shape); builds the
        cameras if needed, rebuilds the render's BVH and captures the render again."""
        self.render()
        self.hidden_groups = tuple(groups)
        with wp.ScopedDevice(self.model.device):
            self._build_bvh()
        self._rerender()
        self.stale = True

    def _rerender(self) -> None:
        """Render once eagerly (compiles what a new setting needs) and capture the render again."""
        with wp.ScopedDevice(self.model.device):
            self._render_body()
            self._graph = self._capture() if self.capture else None

    def _capture(self):
        try:
            with wp.ScopedCapture(device=self.model.device) as cap:
                self._render_body()
        except Exception:  # pragma: no cover - depends on the Warp build; eager rendering stays correct
            return None
        return cap.graph
