"""A compiled scene with an offscreen renderer: a cell, a model, a spec or a bare booth, with
an optional film-thickness mesh composited over it by depth.

Units: positions [m], joint positions [rad], image sizes in pixels (width, height).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from paintcell.execution.cell import Cell
from paintcell.output.render_backend import RenderError, backend_name, make_renderer, one_line
from paintcell.output.render_cameras import CameraView
from paintcell.output.render_film import FILM_OFFSET_M, Film, add_film


def booth_spec(extent_m: float = 3.0, floor_z_m: float = -1.0) -> mujoco.MjSpec:
    """A bare booth: grey floor at `floor_z_m` [m], key and fill lights, no robot.

    extent_m: half size of the floor and height of the key light [m].
    """
    spec = mujoco.MjSpec()
    spec.modelname = "booth"
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    sky = spec.add_texture(name="booth_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                           builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.93, 0.94, 0.96],
                           rgb2=[0.72, 0.75, 0.8], width=64, height=64)
    del sky  # a skybox texture needs no material: MuJoCo draws it as the background
    spec.worldbody.add_geom(name="booth_floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                            size=[extent_m, extent_m, 0.05], pos=[0.0, 0.0, floor_z_m],
                            rgba=[0.55, 0.57, 0.6, 1.0], contype=0, conaffinity=0)
    spec.worldbody.add_light(name="key", pos=[0.5 * extent_m, -0.5 * extent_m, 1.5 * extent_m],
                             dir=[-0.3, 0.3, -1.0], diffuse=[0.6, 0.6, 0.6])
    return spec


def _spec_of(scene: Any) -> mujoco.MjSpec | None:
    """A private copy of the scene's MjSpec (Cell.spec, an MjSpec), or None."""
    if isinstance(scene, mujoco.MjSpec):
        return scene.copy()
    spec = getattr(scene, "spec", None)
    if isinstance(spec, mujoco.MjSpec):
        return spec.copy()
    return None


def _model_of(scene: Any) -> mujoco.MjModel | None:
    if isinstance(scene, mujoco.MjModel):
        return scene
    model = getattr(scene, "model", None)
    return model if isinstance(model, mujoco.MjModel) else None


def robot_qpos_adr(scene: Any, model: mujoco.MjModel) -> np.ndarray | None:
    """qpos addresses (n,) of the robot joints, in the robot's joint order, or None.

    A `paintcell.execution.cell.Cell` knows them (`Cell.qpos_adr`, indexed when the cell was
    compiled). Any other
    scene is a plain model: the robot's joints are looked up by name in `model` — the names from
    `scene.joint_names` or `scene.robot.joint_names`, each matched exactly or else as the unique
    joint whose name ends with it (a robot attached under a prefix, e.g. "robot/joint_1"). None
    when the scene names no joints or a name is missing or ambiguous: `SceneRenderer.set_q` then
    writes q into the model's first qpos entries.
    """
    if isinstance(scene, Cell):
        return np.asarray(scene.qpos_adr, int).copy()
    names = getattr(scene, "joint_names", None)
    if names is None:
        names = getattr(getattr(scene, "robot", None), "joint_names", None)
    if names is None:
        return None
    adr = []
    for n in names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)
        if jid < 0:
            cands = [j for j in range(model.njnt) if (mujoco.mj_id2name(
                model, mujoco.mjtObj.mjOBJ_JOINT, j) or "").endswith(n)]
            if len(cands) != 1:
                return None
            jid = cands[0]
        adr.append(int(model.jnt_qposadr[jid]))
    return np.asarray(adr, int)


def _film_spec_like(model: mujoco.MjModel, data: mujoco.MjData, film: Film) -> mujoco.MjSpec:
    """A spec with only `film`, lights and copies of `model`'s cameras (world poses at `data`),
    so that a render of it lines up pixel for pixel with a render of `model`."""
    spec = mujoco.MjSpec()
    spec.modelname = "film_overlay"
    spec.visual.headlight.ambient = model.vis.headlight.ambient.copy()
    spec.visual.headlight.diffuse = model.vis.headlight.diffuse.copy()
    spec.worldbody.add_light(name="key", pos=[0, 0, 5], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             diffuse=[0.6, 0.6, 0.6], castshadow=False)
    for i in range(model.ncam):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, data.cam_xmat[i])
        spec.worldbody.add_camera(name=mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i)
                                  or f"camera{i}", pos=data.cam_xpos[i].copy(), quat=quat,
                                  fovy=float(model.cam_fovy[i]))
    add_film(spec, film)
    return spec


class SceneRenderer:
    """A compiled scene (a cell, an MjSpec, an MjModel, or a bare booth) with an offscreen
    renderer; optionally with a film-thickness mesh.

    scene: a `paintcell.execution.cell.Cell` (its spec; joint vectors go to `Cell.qpos_adr`), an
    `MjModel`, an
        `MjSpec` (the film is added to a copy), or None for `booth_spec()`.
    film: the thickness map to draw, or None. With a compiled model the film lives in a second
        model that shares the cameras and clip planes; the two renders are composited by depth
        (the film, lifted 0.5 mm off the part, wins over the part; the robot in front wins).
    size: (width, height) [px]; shadows: MuJoCo shadow pass (off: several × faster on software
        GL). cameras: extra named `CameraView`s usable by name in `render`.
    """

    def __init__(self, scene: Any = None, film: Film | None = None,
                 size: tuple[int, int] = (640, 480), shadows: bool = False,
                 cameras: Mapping[str, CameraView] | None = None) -> None:
        width, height = int(size[0]), int(size[1])
        if width < 8 or height < 8 or width > 8192 or height > 8192:
            raise RenderError(f"image size {size} px out of range: use 8..8192 per side")
        backend_name()
        self.size = (width, height)
        self.cameras: dict[str, CameraView] = dict(cameras or {})
        self._film_r: mujoco.Renderer | None = None
        self._film_cache: dict[Any, tuple[np.ndarray, np.ndarray]] = {}
        self._renderer: mujoco.Renderer | None = None
        spec = _spec_of(scene)
        if scene is None:
            # The cell's floor is z = 0; a part placed around the origin gets one below it.
            z0 = -1.0 if film is None else min(0.0, float(film.vertices_world[:, 2].min()) - 0.25)
            spec = booth_spec(floor_z_m=z0)
        if spec is not None:
            if film is not None:
                add_film(spec, film)
            model = _compile(spec)
        else:
            model = _model_of(scene)
            if model is None:
                raise RenderError(f"cannot render a {type(scene).__name__}: pass a Cell, an "
                                  "MjModel, an MjSpec or None")
        _fit_offscreen(model, width, height)
        self.model = model
        self.data = mujoco.MjData(model)
        mujoco.mj_forward(model, self.data)
        self.qpos_adr = robot_qpos_adr(scene, model) if scene is not None else None
        home = getattr(scene, "q_home", None)
        if home is not None and self.qpos_adr is not None and len(home) == len(self.qpos_adr):
            self.set_q(home)
        self._renderer = make_renderer(model, width, height)
        if spec is None and film is not None:
            fmodel = _compile(_film_spec_like(model, self.data, film))
            _fit_offscreen(fmodel, width, height)
            # Same free-camera field of view and clip planes: pixels and depths line up.
            fmodel.vis.global_.fovy = model.vis.global_.fovy
            fmodel.vis.map.znear = model.vis.map.znear
            fmodel.vis.map.zfar = model.vis.map.zfar
            fmodel.stat.extent = model.stat.extent
            fmodel.stat.center = model.stat.center
            self._film_model = fmodel
            self._film_data = mujoco.MjData(fmodel)
            mujoco.mj_forward(fmodel, self._film_data)
            self._film_r = make_renderer(fmodel, width, height)
        self.set_shadows(shadows)

    def set_shadows(self, on: bool) -> None:
        """Turn MuJoCo's shadow pass on or off (off by default: much faster)."""
        for r in (self._renderer, self._film_r):
            if r is not None:
                r.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = int(bool(on))

    def set_q(self, q: npt.ArrayLike) -> None:
        """Set the robot joint positions (n,) [rad] and run `mj_forward`."""
        q = np.asarray(q, float).reshape(-1)
        adr = self.qpos_adr if self.qpos_adr is not None else np.arange(len(q))
        if len(adr) != len(q) or (len(adr) and adr.max() >= self.model.nq):
            raise RenderError(f"joint vector has {len(q)} values but the scene's robot has "
                              f"{len(adr)} joints (model nq = {self.model.nq})")
        self.data.qpos[adr] = q
        mujoco.mj_forward(self.model, self.data)

    def _camera(self, camera: CameraView | str | None) -> mujoco.MjvCamera | str:
        if isinstance(camera, CameraView):
            return camera.to_mjv()
        if camera is None:
            cam = mujoco.MjvCamera()
            mujoco.mjv_defaultFreeCamera(self.model, cam)
            return cam
        if camera in self.cameras:
            return self.cameras[camera].to_mjv()
        if mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, camera) >= 0:
            return camera
        names = sorted(self.cameras) + [mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_CAMERA,
                                                          i) for i in range(self.model.ncam)]
        raise RenderError(f"unknown camera {camera!r}: use one of {names} or a CameraView")

    def render(self, camera: CameraView | str | None = None,
               q: npt.ArrayLike | None = None) -> np.ndarray:
        """(H, W, 3) uint8 RGB frame from `camera`, robot at `q` (n,) [rad] if given."""
        if self._renderer is None:
            raise RenderError("renderer is closed; make a new SceneRenderer")
        if q is not None:
            self.set_q(q)
        cam = self._camera(camera)
        self._renderer.update_scene(self.data, camera=cam)
        rgb = self._renderer.render().copy()
        if self._film_r is None:
            return rgb
        # The film model is static: its colour and depth depend on the camera only (cached).
        key = camera if isinstance(camera, CameraView | str | None) else id(camera)
        if key not in self._film_cache:
            self._film_r.update_scene(self._film_data, camera=cam)
            self._film_cache[key] = (self._film_r.render().copy(), _depth(self._film_r))
        film_rgb, film_depth = self._film_cache[key]
        depth = _depth(self._renderer)
        far = float(self._film_model.vis.map.zfar * self._film_model.stat.extent)
        # The film is lifted FILM_OFFSET_M off the part: it wins over the part's own surface;
        # anything nearer the camera than the film (the robot) wins over the film.
        show = (film_depth < 0.999 * far) & (film_depth < depth + 0.2 * FILM_OFFSET_M)
        rgb[show] = film_rgb[show]
        return rgb

    def close(self) -> None:
        """Free the GL contexts."""
        for r in (self._renderer, self._film_r):
            if r is not None:
                r.close()
        self._renderer = self._film_r = None

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _depth(r: mujoco.Renderer) -> np.ndarray:
    """(H, W) distance along the view axis [m] of the scene last updated in `r`."""
    r.enable_depth_rendering()
    try:
        return r.render()
    finally:
        r.disable_depth_rendering()


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    try:
        return spec.compile()
    except ValueError as e:
        raise RenderError(f"scene does not compile for rendering: {one_line(e)}") from e


def _fit_offscreen(model: mujoco.MjModel, width: int, height: int) -> None:
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
