"""The simulated RGB-D camera: PyBullet's TinyRenderer seen through an OpenCV pinhole model.

Conventions (shared notes/conventions.md):
- Intrinsics K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; pixel (u, v) = (column, row), the centre of
  the top-left pixel at (0, 0). The OpenGL projection is built from K, so an off-centre principal
  point is honoured exactly (TinyRenderer samples each pixel at one point: measured, column u sees
  the ray through u and row v the ray through v under the K reported here).
- `T_world_camera` maps OpenCV camera coordinates (x right, y down, z forward) to the world.
- Depth is float32 metres along the optical axis, NaN where nothing was rendered or a reading
  dropped out.

The default pose looks down at the workspace from above its far side (x > workspace, tilted ~29°
back towards the robot), so an arm at its home pose (gripper 0.25 m over the workspace centre)
projects onto the near edge of the workspace rather than onto its middle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pybullet as p

from foldbot.errors import ConfigError, require
from foldbot.sim.layout import CellLayout
from foldbot.types import CameraIntrinsics, Observation

_OPENCV_FROM_GL = np.diag([1.0, -1.0, -1.0, 1.0])


def _rigid_pose(name: str, value: object) -> tuple[tuple[float, ...], ...]:
    """A 4×4 rigid transform (nested tuples of floats), or ConfigError naming `name`."""
    T = np.asarray(_finite_vector(name, value, 16)).reshape(4, 4)
    R = T[:3, :3]
    require(
        np.allclose(R @ R.T, np.eye(3), atol=1e-6)
        and abs(np.linalg.det(R) - 1.0) < 1e-6
        and np.allclose(T[3], [0.0, 0.0, 0.0, 1.0]),
        f"{name} must be a rigid 4×4 transform (orthonormal rotation, last row 0 0 0 1), "
        f"got {T.tolist()!r}",
    )
    return tuple(tuple(float(v) for v in row) for row in T)


def _finite_vector(name: str, value: object, size: int) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be {size} finite numbers, got {value!r}") from None
    if arr.size != size or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} must be {size} finite numbers, got {value!r}")
    return tuple(float(v) for v in arr)


def look_at(
    eye: tuple[float, float, float],
    target: tuple[float, float, float],
    up: tuple[float, float, float] = (0.0, 0.0, 1.0),
) -> np.ndarray:
    """4×4 T_world_camera (OpenCV axes) of a camera at `eye` looking at `target`, `up` upwards."""
    e, t, u = (np.asarray(v, dtype=float) for v in (eye, target, up))
    z = t - e
    dist = np.linalg.norm(z)
    if dist < 1e-6:
        raise ConfigError(f"camera eye {e.tolist()} and target {t.tolist()} (m) must differ")
    z /= dist
    x = np.cross(z, u)  # image right; image down = z × x, i.e. image up ≈ `up`
    if np.linalg.norm(x) < 1e-6:
        raise ConfigError(
            f"camera up {tuple(u)} must not be parallel to the viewing direction {tuple(z)}"
        )
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, e
    return T


def opengl_projection_from_K(
    K: np.ndarray, width: int, height: int, near: float, far: float
) -> np.ndarray:
    """Row-major 4×4 OpenGL projection reproducing OpenCV intrinsics K in TinyRenderer's raster."""
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    P = np.zeros((4, 4))
    P[0, 0] = 2.0 * fx / width
    P[0, 2] = 1.0 - 2.0 * cx / width
    P[1, 1] = 2.0 * fy / height
    # TinyRenderer flips rows after rasterising, which shifts the sampled ray by one row.
    P[1, 2] = 2.0 * (cy + 1.0) / height - 1.0
    P[2, 2] = -(far + near) / (far - near)
    P[2, 3] = -2.0 * far * near / (far - near)
    P[3, 2] = -1.0
    return P


def depth_from_buffer(buffer: np.ndarray, near: float, far: float) -> np.ndarray:
    """Metres along the optical axis from OpenGL depth-buffer values d ∈ [0, 1]; NaN at d ≥ 1."""
    d = np.asarray(buffer, dtype=np.float64)
    z = far * near / (far - (far - near) * d)
    z[d >= 1.0 - 1e-7] = np.nan
    return z.astype(np.float32)


@dataclass(frozen=True)
class Lighting:
    """TinyRenderer lighting (one directional light plus ambient), randomisable per scene."""

    direction: tuple[float, float, float] = (0.4, 0.2, 1.0)
    """Direction from the scene towards the light (world frame, need not be unit length)."""
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    """Light colour (RGB, each 0..1)."""
    distance: float = 2.0
    """Light distance (m), used by TinyRenderer for its shadow map."""
    ambient: float = 0.6
    """Ambient coefficient (0..1)."""
    diffuse: float = 0.35
    """Diffuse coefficient (0..1)."""
    specular: float = 0.05
    """Specular coefficient (0..1)."""
    shadow: bool = False
    """Cast shadows (costs an extra render pass)."""

    def __post_init__(self) -> None:
        d = _finite_vector("lighting direction", self.direction, 3)
        require(np.linalg.norm(d) > 1e-9, f"lighting direction must be non-zero, got {d!r}")
        object.__setattr__(self, "direction", d)
        c = _finite_vector("lighting color", self.color, 3)
        require(all(0.0 <= v <= 1.0 for v in c), f"lighting color must be in [0, 1]³, got {c!r}")
        object.__setattr__(self, "color", c)
        require(
            math.isfinite(self.distance) and self.distance > 0.0,
            f"lighting distance must be > 0 m, got {self.distance!r}",
        )
        for name in ("ambient", "diffuse", "specular"):
            v = getattr(self, name)
            require(
                isinstance(v, int | float) and 0.0 <= v <= 1.0,
                f"lighting {name} must be in [0, 1], got {v!r}",
            )


DEFAULT_EYE = (1.05, 0.0, 1.75)
"""Default camera position (m): 0.6 m beyond the workspace centre, 1.0 m above the table."""
DEFAULT_TARGET = (0.50, 0.0, 0.75)
"""Default look-at point (m), on the table, chosen so the workspace is centred in the image."""
DEFAULT_UP = (-1.0, 0.0, 0.0)
"""Default image-up direction: towards the robot (the robot appears at the top of the image)."""
DEFAULT_F_640x480 = 880.0
"""Default focal length (px) at 640×480: the 0.6 m workspace plus ≥ 5 cm margin fills the frame."""


@dataclass(frozen=True)
class CameraConfig:
    """An RGB-D camera: image size, OpenCV intrinsics, clipping planes, pose, noise and lighting."""

    width: int = 640
    """Image width (px)."""
    height: int = 480
    """Image height (px)."""
    fx: float | None = None
    """Focal length along x (px); None = 880 px scaled to the image size (see DEFAULT_F_640x480)."""
    fy: float | None = None
    """Focal length along y (px); None = fx (square pixels)."""
    cx: float | None = None
    """Principal point column (px); None = image centre (width − 1) / 2."""
    cy: float | None = None
    """Principal point row (px); None = image centre (height − 1) / 2."""
    near: float = 0.4
    """Near clipping plane (m). Kept tight around the scene for depth-buffer precision."""
    far: float = 2.0
    """Far clipping plane (m); beyond it depth reads NaN."""
    eye: tuple[float, float, float] = DEFAULT_EYE
    """Camera position (world, m); ignored when `pose` is given."""
    target: tuple[float, float, float] = DEFAULT_TARGET
    """Point the optical axis passes through (world, m); ignored when `pose` is given."""
    up: tuple[float, float, float] = DEFAULT_UP
    """World direction that appears upwards in the image; ignored when `pose` is given."""
    pose: tuple[tuple[float, ...], ...] | None = None
    """Optional 4×4 T_world_camera (OpenCV axes), overriding eye/target/up."""
    reported_pose: tuple[tuple[float, ...], ...] | None = None
    """Optional 4×4 T_world_camera the Observations carry instead of the true one: where a
    calibration found the camera, which perception then works from, as on a real cell (the
    image is still rendered from where the camera truly is). None: the true pose."""
    reported_pose_source: str = ""
    """Where `reported_pose` came from (a calibration file), for the episode's record."""
    depth_noise: float = 0.0
    """Depth noise coefficient a (1/m): Gaussian σ = a·z² at depth z; 0.001 → 1.2 mm at 1.1 m."""
    depth_dropout: float = 0.0
    """Probability that a depth pixel reads unknown (NaN), as real sensors' holes."""
    rgb_noise: float = 0.0
    """Gaussian RGB noise σ (intensity levels 0..255)."""
    seed: int = 0
    """Seed of the camera's own noise generator (used when observe() gets no rng)."""
    lighting: Lighting = field(default_factory=Lighting)
    """Lighting of the rendered scene."""

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            require(
                isinstance(v, int | np.integer) and not isinstance(v, bool) and 16 <= v <= 4096,
                f"camera {name} must be an integer in [16, 4096] px, got {v!r}",
            )
        scale = min(self.width / 640.0, self.height / 480.0)
        fx = DEFAULT_F_640x480 * scale if self.fx is None else self.fx
        fy = fx if self.fy is None else self.fy
        cx = (self.width - 1) / 2.0 if self.cx is None else self.cx
        cy = (self.height - 1) / 2.0 if self.cy is None else self.cy
        for name, v in (("fx", fx), ("fy", fy)):
            require(
                isinstance(v, int | float) and math.isfinite(v) and v > 0.0,
                f"camera {name} must be a finite focal length > 0 px, got {v!r}",
            )
        for name, v, size in (("cx", cx, self.width), ("cy", cy, self.height)):
            require(
                isinstance(v, int | float) and math.isfinite(v) and 0.0 <= v <= size,
                f"camera {name} must be in [0, {size}] px, got {v!r}",
            )
        object.__setattr__(self, "fx", float(fx))
        object.__setattr__(self, "fy", float(fy))
        object.__setattr__(self, "cx", float(cx))
        object.__setattr__(self, "cy", float(cy))
        require(
            isinstance(self.near, int | float) and math.isfinite(self.near) and self.near > 0.0,
            f"camera near must be > 0 m, got {self.near!r}",
        )
        require(
            isinstance(self.far, int | float)
            and math.isfinite(self.far)
            and self.near < self.far <= 1000.0 * self.near,
            f"camera far must be in (near, 1000·near] = ({self.near}, {1000.0 * self.near}] m, "
            f"got {self.far!r}",
        )
        for name in ("eye", "target", "up"):
            object.__setattr__(self, name, _finite_vector(f"camera {name}", getattr(self, name), 3))
        if self.pose is not None:
            object.__setattr__(self, "pose", _rigid_pose("camera pose", self.pose))
        else:
            look_at(self.eye, self.target, self.up)  # validates eye ≠ target and up
        if self.reported_pose is not None:
            object.__setattr__(
                self, "reported_pose", _rigid_pose("camera reported_pose", self.reported_pose)
            )
        require(
            isinstance(self.reported_pose_source, str),
            f"camera reported_pose_source must be a string, got {self.reported_pose_source!r}",
        )
        for name in ("depth_noise", "rgb_noise"):
            v = getattr(self, name)
            require(
                isinstance(v, int | float) and math.isfinite(v) and v >= 0.0,
                f"camera {name} must be ≥ 0, got {v!r}",
            )
        require(
            isinstance(self.depth_dropout, int | float) and 0.0 <= self.depth_dropout < 1.0,
            f"camera depth_dropout must be in [0, 1), got {self.depth_dropout!r}",
        )
        require(
            isinstance(self.lighting, Lighting),
            f"camera lighting must be a Lighting, got {self.lighting!r}",
        )

    @property
    def K(self) -> np.ndarray:
        """3×3 OpenCV intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def intrinsics(self) -> CameraIntrinsics:
        """Intrinsics as carried by an Observation."""
        return CameraIntrinsics(width=int(self.width), height=int(self.height), K=self.K)

    @property
    def T_world_camera(self) -> np.ndarray:
        """4×4 transform from OpenCV camera coordinates to the world: where the camera is."""
        if self.pose is not None:
            return np.array(self.pose, dtype=float)
        return look_at(self.eye, self.target, self.up)

    @property
    def reported_T_world_camera(self) -> np.ndarray:
        """4×4 T_world_camera the Observations carry: `reported_pose`, else the true pose."""
        if self.reported_pose is not None:
            return np.array(self.reported_pose, dtype=float)
        return self.T_world_camera


class RGBDCamera:
    """A fixed RGB-D camera rendering a PyBullet client with TinyRenderer (no display needed)."""

    def __init__(self, client: int, config: CameraConfig | None = None) -> None:
        self.client = int(client)
        self.config = config or CameraConfig()
        self.lighting = self.config.lighting
        """Current lighting; assign a new Lighting to change it between frames."""
        self._rng = np.random.default_rng(self.config.seed)
        cfg = self.config
        self._T_world_camera = cfg.T_world_camera
        view = _OPENCV_FROM_GL @ np.linalg.inv(self._T_world_camera)  # world → OpenGL camera
        self._view = view.T.reshape(-1).tolist()  # PyBullet wants column-major
        proj = opengl_projection_from_K(cfg.K, cfg.width, cfg.height, cfg.near, cfg.far)
        self._proj = proj.T.reshape(-1).tolist()

    @property
    def T_world_camera(self) -> np.ndarray:
        """4×4 transform from OpenCV camera coordinates to the world, where the camera truly is
        (a copy). GROUND TRUTH where a calibration's pose is reported instead."""
        return self._T_world_camera.copy()

    @property
    def reported_T_world_camera(self) -> np.ndarray:
        """The camera pose its Observations carry (a copy): a calibration's, or the true one."""
        return self.config.reported_T_world_camera

    @property
    def intrinsics(self) -> CameraIntrinsics:
        """The camera's OpenCV intrinsics."""
        return self.config.intrinsics

    def _render(self, with_segmentation: bool) -> tuple:
        cfg, light = self.config, self.lighting
        if not isinstance(light, Lighting):
            raise ConfigError(f"camera lighting must be a Lighting, got {light!r}")
        flags = 0 if with_segmentation else p.ER_NO_SEGMENTATION_MASK
        return p.getCameraImage(
            cfg.width,
            cfg.height,
            viewMatrix=self._view,
            projectionMatrix=self._proj,
            lightDirection=list(light.direction),
            lightColor=list(light.color),
            lightDistance=light.distance,
            shadow=int(light.shadow),
            lightAmbientCoeff=light.ambient,
            lightDiffuseCoeff=light.diffuse,
            lightSpecularCoeff=light.specular,
            renderer=p.ER_TINY_RENDERER,
            flags=flags,
            physicsClientId=self.client,
        )

    def observe(
        self,
        joint_positions: np.ndarray | None = None,
        stamp: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> Observation:
        """Render one RGB-D frame (with the configured noise) as an Observation."""
        cfg = self.config
        _, _, rgba, depth_buffer, _ = self._render(with_segmentation=False)
        rgb = np.asarray(rgba, dtype=np.uint8).reshape(cfg.height, cfg.width, 4)[..., :3].copy()
        depth = depth_from_buffer(
            np.asarray(depth_buffer, dtype=np.float32).reshape(cfg.height, cfg.width),
            cfg.near,
            cfg.far,
        )
        gen = rng if rng is not None else self._rng
        if cfg.depth_noise > 0.0:
            noise = gen.standard_normal(depth.shape, dtype=np.float32)
            depth += (cfg.depth_noise * depth * depth) * noise
        if cfg.depth_dropout > 0.0:
            depth[gen.random(depth.shape) < cfg.depth_dropout] = np.nan
        if cfg.rgb_noise > 0.0:
            noisy = rgb + gen.normal(0.0, cfg.rgb_noise, rgb.shape).astype(np.float32)
            rgb = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
        q = np.zeros(0) if joint_positions is None else np.asarray(joint_positions, dtype=float)
        return Observation(
            rgb=rgb,
            depth=depth,
            intrinsics=cfg.intrinsics,
            T_world_camera=self.reported_T_world_camera,
            joint_positions=q.copy(),
            stamp=float(stamp),
        )

    def render_segmentation(self) -> np.ndarray:
        """H×W int body-id map (−1 = background). Simulator GROUND TRUTH: for the oracle only."""
        cfg = self.config
        seg = self._render(with_segmentation=True)[4]
        return np.asarray(seg, dtype=np.int64).reshape(cfg.height, cfg.width)


def camera_for_layout(camera: CameraConfig, layout: CellLayout) -> CameraConfig:
    """The camera as placed in a cell laid out as `layout`: one at the default pose (DEFAULT_EYE,
    DEFAULT_TARGET: over the default cell's workspace) moved with the workspace centre and the
    table top (CellLayout.workspace_shift), so it frames that workspace as it frames the
    default one; a camera given its own pose (eye, target or `pose`) is left where it is."""
    if camera.pose is not None or (camera.eye, camera.target) != (DEFAULT_EYE, DEFAULT_TARGET):
        return camera
    shift = layout.workspace_shift()
    if not any(shift):
        return camera
    return replace(
        camera,
        eye=tuple(a + d for a, d in zip(DEFAULT_EYE, shift, strict=True)),
        target=tuple(a + d for a, d in zip(DEFAULT_TARGET, shift, strict=True)),
    )
