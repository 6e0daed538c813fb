"""The part's geoms in a MuJoCo cell: the exact surface as a visual mesh and thin convex
collision slabs (MuJoCo collides meshes through their convex hulls, so a curved shell is cut into
pieces). `paintcell.execution.cell` and `paintcell.booth.booth_cell` add them to their part
body.

A part that stands still (the single-robot cell) may carry its slabs on MuJoCo's world body
instead (`collision_body` = the world body, `T_body_part` its placement): MuJoCo's broadphase
then skips them (every step it bounds each geom of every other collidable body, 88 slabs on the
door: a third of the collision time) and reaches them through the world body's bounding-volume
tree instead. The slabs, and so the contacts, are the same; `move_part_collision` moves them with
the part when an execution displaces it.
"""

from __future__ import annotations

import mujoco
import numpy as np

from paintcell.core.transforms import quat_wxyz_from_matrix
from paintcell.surface.surface_data import Surface


def add_part_geoms(spec: mujoco.MjSpec, part: mujoco.MjsBody, surface: Surface,
                   collision_piece_m: float, shell_thickness_m: float,
                   collision_body: mujoco.MjsBody | None = None,
                   T_body_part: np.ndarray | None = None) -> None:
    """Add the part's geoms to body `part`: the exact surface as a visual mesh (no contacts) and
    thin convex collision slabs (`_collision_pieces`, pieces ~collision_piece_m [m] across,
    shell_thickness_m [m] thick), on `collision_body` (default `part`) at the (4, 4) pose
    `T_body_part` of the part frame in that body (default identity)."""
    body = part if collision_body is None else collision_body
    pose: dict[str, np.ndarray] = {}
    if T_body_part is not None:
        pose = {"pos": np.asarray(T_body_part[:3, 3], float),
                "quat": quat_wxyz_from_matrix(np.asarray(T_body_part[:3, :3], float))}
    vis = spec.add_mesh(name="part_surface")
    vis.uservert = np.ascontiguousarray(surface.vertices, float).ravel()
    vis.userface = np.ascontiguousarray(surface.faces, np.int32).ravel()
    vis.usernormal = np.ascontiguousarray(surface.normals, float).ravel()
    vis.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    part.add_geom(name="part_visual", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="part_surface",
                  contype=0, conaffinity=0, group=1, density=0.0, rgba=[0.75, 0.77, 0.8, 1.0])
    for i, cloud in enumerate(_collision_pieces(surface, collision_piece_m, shell_thickness_m)):
        m = spec.add_mesh(name=f"part_collision_{i}")
        m.uservert = np.ascontiguousarray(cloud, float).ravel()
        m.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        body.add_geom(name=f"part_collision_{i}", type=mujoco.mjtGeom.mjGEOM_MESH,
                      meshname=f"part_collision_{i}", group=3, density=0.0,
                      rgba=[0.5, 0.5, 0.5, 0.3], **pose)


def move_part_collision(model: mujoco.MjModel, body_id: int, T_move: np.ndarray) -> None:
    """Move every geom of `body_id` (the world body holding the part's slabs) by the world-frame
    rigid motion T_move (4, 4), in place, with that body's bounding-volume tree: each node's box
    becomes the axis-aligned box of the moved box (it may grow under a rotation, never shrink
    below what it holds, so MuJoCo's midphase still reaches every slab; the slabs' own boxes are
    in their geom frames and move with them)."""
    R, t = T_move[:3, :3], T_move[:3, 3]
    a, n = int(model.body_geomadr[body_id]), int(model.body_geomnum[body_id])
    g = slice(a, a + n)
    model.geom_pos[g] = model.geom_pos[g] @ R.T + t
    qm = np.zeros(4)
    mujoco.mju_mat2Quat(qm, np.ascontiguousarray(R).ravel())
    for i in range(a, a + n):
        out = np.zeros(4)
        mujoco.mju_mulQuat(out, qm, model.geom_quat[i])
        model.geom_quat[i] = out
    b, nb = int(model.body_bvhadr[body_id]), int(model.body_bvhnum[body_id])
    if b >= 0 and nb > 0:
        box = model.bvh_aabb[b:b + nb]
        box[:, :3] = box[:, :3] @ R.T + t
        box[:, 3:] = box[:, 3:] @ np.abs(R).T


def _collision_pieces(surface: Surface, piece_m: float, thickness_m: float) -> list[np.ndarray]:
    """Vertex clouds (part frame) of thin convex slabs that cover the shell.

    Faces are binned by centroid into cubes of edge `piece_m`; each bin's vertices are offset by
    ±thickness/2 along their normals; MuJoCo takes the convex hull of each cloud. The hull of a
    piece deviates from the shell by at most its sagitta, piece²/(8 R) (1.3 mm for 0.1 m on R=1 m).
    """
    v, f, nrm = surface.vertices, surface.faces, surface.normals
    cent = v[f].mean(axis=1)
    key = np.floor((cent - cent.min(0)) / piece_m).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    order = np.argsort(inv.ravel(), kind="stable")
    bounds = np.searchsorted(inv.ravel()[order], np.arange(inv.max() + 2))
    half = 0.5 * thickness_m
    pieces = []
    for b in range(len(bounds) - 1):
        faces_b = f[order[bounds[b]:bounds[b + 1]]]
        idx = np.unique(faces_b)
        pieces.append(np.vstack([v[idx] + half * nrm[idx], v[idx] - half * nrm[idx]]))
    return pieces
