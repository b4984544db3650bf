"""A Newton model's shapes as rerun archetypes, logged once (static) under their body's entity.

Every shape of the drawn rows is logged, whatever its flags: visual shapes (``ShapeFlags.VISIBLE``) under
``<body>/visual/<name>``, collision-only shapes under ``<body>/collision/<name>``, sites (``ShapeFlags.SITE``:
TCPs, camera mounts) as wireframes under ``<body>/site/<name>``. A body's collision-only shapes are hidden by
the default blueprint when the same body also has visual shapes (they would overlap its visual geometry).
Bodies live at ``world/<row>/<body>`` (a per-step transform), static shapes (``shape_body == -1``) at
``world/<row>/static``, shapes of no world (the ground plane) at ``world/global``. Lengths in metres.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import newton
import numpy as np
import rerun as rr

G = newton.GeoType
GROUND_MARGIN = 2.0
"""Ground drawn this far [m] beyond the outermost rows when the plane is infinite (``shape_scale`` 0)."""


def entity_name(label: str, taken: set[str]) -> str:
    """The last part of a Newton label as one rerun path part, unique among ``taken`` (which it joins)."""
    base = re.sub(r"[^A-Za-z0-9_\-]", "_", label.rsplit("/", 1)[-1]) or "unnamed"
    name, k = base, 1
    while name in taken:
        name, k = f"{base}_{k}", k + 1
    taken.add(name)
    return name


def shape_kind(flags: int) -> str:
    """``site``, ``visual`` or ``collision`` (a shape that only collides) from ``Model.shape_flags``."""
    if flags & int(newton.ShapeFlags.SITE):
        return "site"
    return "visual" if flags & int(newton.ShapeFlags.VISIBLE) else "collision"


def _mesh3d(mesh: newton.Mesh, scale, color, offset=(0.0, 0.0, 0.0)) -> rr.Mesh3D:
    s = np.asarray(scale, dtype=np.float32)
    verts = np.asarray(mesh.vertices, dtype=np.float32) * s + np.asarray(offset, dtype=np.float32)
    normals = mesh.normals
    if normals is not None:  # normals of a scaled surface scale by 1 / scale
        normals = np.asarray(normals, dtype=np.float32) / np.where(s == 0, 1.0, s)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return rr.Mesh3D(
        vertex_positions=verts,
        triangle_indices=np.asarray(mesh.indices).reshape(-1, 3),
        vertex_normals=normals,
        albedo_factor=color,
    )


def _heightfield(src, color) -> rr.Mesh3D:
    heights = src.min_z + src.data * (src.max_z - src.min_z)  # as Newton's own viewer draws it
    mesh = newton.Mesh.create_heightfield(
        heightfield=heights.T, extent_x=2 * src.hx, extent_y=2 * src.hy, ground_z=src.min_z, compute_inertia=False
    )
    return _mesh3d(mesh, (1.0, 1.0, 1.0), color)


def shape_archetype(
    kind: int, scale, src, color, *, site: bool = False, plane_extent=(10.0, 10.0), plane_center=(0.0, 0.0)
):
    """The rerun archetype drawing one shape in its own frame (``Model.shape_type`` / ``shape_scale`` /
    ``shape_source`` conventions: capsule, cylinder and cone along local Z; plane normal local Z).
    ``plane_extent`` (x, y) [m] and ``plane_center`` are used for infinite planes."""
    sx, sy, sz = (float(v) for v in scale)
    fill = "majorwireframe" if site else "solid"
    if kind == G.BOX:
        return rr.Boxes3D(half_sizes=[[sx, sy, sz]], colors=[color], fill_mode=fill)
    if kind == G.SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[sx, sx, sx]], colors=[color], fill_mode=fill)
    if kind == G.ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[[sx, sy, sz]], colors=[color], fill_mode=fill)
    if kind == G.CAPSULE:  # rerun's capsule starts at its translation and runs along +Z
        return rr.Capsules3D(lengths=[2 * sy], radii=[sx], translations=[[0, 0, -sy]], colors=[color], fill_mode=fill)
    if kind == G.CYLINDER:
        return rr.Cylinders3D(lengths=[2 * sy], radii=[sx], colors=[color], fill_mode=fill)
    if kind == G.CONE:
        return _mesh3d(newton.Mesh.create_cone(sx, sy, up_axis=newton.Axis.Z, compute_inertia=False), (1, 1, 1), color)
    if kind in (G.MESH, G.CONVEX_MESH):
        return _mesh3d(src, scale, color)
    if kind == G.PLANE:
        w, h = (2 * sx, 2 * sy) if sx > 0 and sy > 0 else plane_extent
        return _mesh3d(
            newton.Mesh.create_plane(w, h, compute_inertia=False),
            (1, 1, 1),
            color,
            offset=(*(plane_center if sx <= 0 else (0.0, 0.0)), 0.0),
        )
    if kind == G.HFIELD:
        return _heightfield(src, color)
    if kind == G.GAUSSIAN:
        return rr.Points3D(np.asarray(src.positions) * np.asarray(scale), colors=[color], radii=[0.002])
    raise ValueError(f"shape type {kind} ({G(kind).name}) has no rerun drawing; add one in newton_lab/viz/shapes.py")


@dataclass
class LoggedShapes:
    """What ``log_model_shapes`` logged: the entity path of each logged shape (by model shape index) and the
    collision-only shapes hidden by default (their body has visual shapes)."""

    paths: dict[int, str] = field(default_factory=dict)
    hidden: list[str] = field(default_factory=list)


def row_offsets(rows: int, spacing: float) -> np.ndarray:
    """(rows, 3) positions [m] of the drawn rows on a square grid (Newton's worlds all sit at the origin)."""
    cols = int(np.ceil(np.sqrt(max(rows, 1))))
    return np.array([[(w // cols) * spacing, (w % cols) * spacing, 0.0] for w in range(rows)], dtype=np.float32)


def log_model_shapes(
    rec: rr.RecordingStream, model: newton.Model, body_paths: dict[int, str], rows: int, offsets: np.ndarray
) -> LoggedShapes:
    """Log every shape of worlds ``< rows`` and of no world (static) on ``rec``; ``body_paths`` maps a
    model body index to its entity path (``world/<row>/<body>``), ``offsets`` (rows, 3) places the rows."""
    stype, scale = model.shape_type.numpy(), model.shape_scale.numpy()
    xform, sbody, sworld = model.shape_transform.numpy(), model.shape_body.numpy(), model.shape_world.numpy()
    flags, colors = model.shape_flags.numpy(), model.shape_color.numpy()
    opacity = model.shape_opacity.numpy() if model.shape_opacity is not None else np.ones(model.shape_count)
    extent = tuple(float(v) + 2 * GROUND_MARGIN for v in np.ptp(offsets[:, :2], axis=0))
    center = tuple(float(v) for v in offsets[:, :2].mean(axis=0))
    for w in range(rows):
        rec.log(f"world/{w}", rr.Transform3D(translation=offsets[w]), static=True)
    visual_bodies = {int(b) for b, f in zip(sbody, flags) if b >= 0 and shape_kind(int(f)) == "visual"}
    out, taken = LoggedShapes(), {}
    for s in range(model.shape_count):
        w, b = int(sworld[s]), int(sbody[s])
        if w >= rows:
            continue
        parent = body_paths[b] if b >= 0 else (f"world/{w}/static" if w >= 0 else "world/global")
        kind = shape_kind(int(flags[s]))
        name = entity_name(model.shape_label[s], taken.setdefault(f"{parent}/{kind}", set()))
        path = f"{parent}/{kind}/{name}"
        color = [*(round(255 * float(c)) for c in colors[s]), round(255 * float(opacity[s]))]
        t = xform[s]
        rec.log(path, rr.Transform3D(translation=t[:3], quaternion=rr.Quaternion(xyzw=t[3:7])), static=True)
        rec.log(
            path,
            shape_archetype(
                int(stype[s]),
                scale[s],
                model.shape_source[s],
                color,
                site=kind == "site",
                plane_extent=extent,
                plane_center=center,
            ),
            static=True,
        )
        out.paths[s] = path
        if kind == "collision" and b in visual_bodies:
            out.hidden.append(path)
    return out
