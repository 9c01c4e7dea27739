"""Speed reference: the same towel in plain PyBullet at the settings Deformable Ravens used.

No foldbot class is involved: a fresh PyBullet client, a plane, a 10 × 10-vertex mass-spring
cloth loaded with `loadSoftBody` from a grid .obj written here, stepped at 1/480 s. One corner
is carried over the cloth onto the opposite corner by a light sphere it is anchored to (as
Ravens' suction gripper anchors one vertex), released, and left to settle, for the simulated
duration foldbot's episodes took. The figure is simulated seconds per wall second; divided by
foldbot's own it says how much foldbot's cell (16 × 16-vertex cloth by default, UR5, joint
control, camera frames) costs over the field's cheapest cloth set-up.

Settings, from Deformable Ravens (Seita et al., ICRA 2021; github.com/DanielTakeshi/
deformable-ravens): `ravens/tasks/defs_cloth.py` `ClothEnv.add_cloth` — `loadSoftBody(...,
mass=0.5, useNeoHookean=0, useBendingSprings=1, useMassSpring=1, springElasticStiffness=40,
springDampingStiffness=0.1, springDampingAllDirections=0, useSelfCollision=1, frictionCoeff=1.0,
useFaceContact=1, collisionMargin=edge_length / 5)` with `n_cuts = 10` (10 × 10 vertices);
`ravens/environment.py` — `resetSimulation(RESET_USE_DEFORMABLE_WORLD)`, gravity −9.8, plane at
z = −0.001, `setTimeStep(1 / hz)` with `hz ≥ 480` asserted for soft bodies; one anchor per grasp
(`_def_nb_anchors = 1`). Their cloth is 0.2 m square; here it has the benchmarked towel's size.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from foldbot.errors import ConfigError

RAVENS_VERTICES = 10
RAVENS_HZ = 480.0
RAVENS_CLOTH = {
    "mass": 0.5,
    "useNeoHookean": 0,
    "useBendingSprings": 1,
    "useMassSpring": 1,
    "springElasticStiffness": 40,
    "springDampingStiffness": 0.1,
    "springDampingAllDirections": 0,
    "useSelfCollision": 1,
    "frictionCoeff": 1.0,
    "useFaceContact": 1,
}


def write_grid_obj(path: Path, width: float, height: float, n: int = RAVENS_VERTICES) -> None:
    """A flat n × n-vertex triangulated grid of width × height metres, centred, z = 0."""
    xs, ys = np.linspace(-width / 2, width / 2, n), np.linspace(-height / 2, height / 2, n)
    lines = [f"v {x:.6f} {y:.6f} 0.0" for y in ys for x in xs]
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i + 1  # .obj indices are 1-based
            b, c, d = a + 1, a + n, a + n + 1
            lines += [f"f {a} {b} {d}", f"f {a} {d} {c}"]
    path.write_text("\n".join(lines) + "\n")


def ravens_speed_reference(
    width: float = 0.30, height: float = 0.30, sim_seconds: float = 10.0
) -> dict:
    """Simulate the reference for `sim_seconds`; return its settings and sim s per wall s."""
    import pybullet_data

    from foldbot.sim import import_pybullet

    p = import_pybullet()

    if not (0.05 <= width <= 1.0 and 0.05 <= height <= 1.0):
        raise ConfigError(f"reference cloth {width} × {height} m; allowed sides: 0.05–1.0 m")
    if not (math.isfinite(sim_seconds) and 0 < sim_seconds <= 600):
        raise ConfigError(f"reference duration {sim_seconds!r} s; allowed: (0, 600] s")
    n = RAVENS_VERTICES
    edge = max(width, height) / (n - 1)
    steps = max(1, round(sim_seconds * RAVENS_HZ))
    client = p.connect(p.DIRECT)
    try:
        p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD, physicsClientId=client)
        p.setGravity(0, 0, -9.8, physicsClientId=client)
        p.setTimeStep(1.0 / RAVENS_HZ, physicsClientId=client)
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=client)
        p.loadURDF("plane.urdf", [0, 0, -0.001], physicsClientId=client)
        with tempfile.TemporaryDirectory(prefix="ravens-ref-") as tmp:
            obj = Path(tmp) / "cloth.obj"
            write_grid_obj(obj, width, height, n)
            cloth = p.loadSoftBody(
                str(obj),
                basePosition=[0, 0, 0.01],
                collisionMargin=edge / 5.0,
                physicsClientId=client,
                **RAVENS_CLOTH,
            )
        verts = np.array(
            p.getMeshData(cloth, -1, flags=p.MESH_DATA_SIMULATION_MESH, physicsClientId=client)[1]
        )
        if len(verts) != n * n:
            raise RuntimeError(f"reference cloth has {len(verts)} vertices, expected {n * n}")
        # The gripper stand-in: a 2 cm sphere with mass, moved by a fixed constraint.
        corner = int(np.argmin(verts[:, 0] + verts[:, 1]))
        target = int(np.argmax(verts[:, 0] + verts[:, 1]))
        start, goal = verts[corner].copy(), verts[target].copy()
        shape = p.createCollisionShape(p.GEOM_SPHERE, radius=0.01, physicsClientId=client)
        ball = p.createMultiBody(0.05, shape, basePosition=start.tolist(), physicsClientId=client)
        p.setCollisionFilterGroupMask(ball, -1, 0, 0, physicsClientId=client)
        hold = p.createConstraint(
            ball, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0], start.tolist(),
            physicsClientId=client,
        )  # fmt: skip
        anchor = p.createSoftBodyAnchor(cloth, corner, ball, -1, physicsClientId=client)
        carry = max(1, int(0.6 * steps))  # carry for 60 % of the time, then release and settle
        t0 = time.perf_counter()
        for k in range(steps):
            if k < carry:
                s = (k + 1) / carry
                pos = start + s * (goal - start)
                pos[2] = start[2] + 0.5 * np.linalg.norm(goal - start) * math.sin(math.pi * s) / 2
                p.changeConstraint(hold, pos.tolist(), maxForce=50, physicsClientId=client)
            elif k == carry:
                p.removeConstraint(anchor, physicsClientId=client)
            p.stepSimulation(physicsClientId=client)
        wall = time.perf_counter() - t0
        final = np.array(
            p.getMeshData(cloth, -1, flags=p.MESH_DATA_SIMULATION_MESH, physicsClientId=client)[1]
        )
    finally:
        p.disconnect(client)
    simulated = steps / RAVENS_HZ
    return {
        "what": "plain PyBullet cloth at Deformable Ravens' settings (10 × 10 vertices, 480 Hz)",
        "vertices": n * n,
        "time_step_s": 1.0 / RAVENS_HZ,
        "cloth_m": [width, height],
        "settings": {**RAVENS_CLOTH, "collisionMargin": edge / 5.0},
        "sim_seconds": simulated,
        "wall_seconds": wall,
        "sim_speed": simulated / wall if wall > 0 else None,
        "carried_corner_end_error_m": float(np.linalg.norm(final[corner, :2] - goal[:2])),
        "finite": bool(np.all(np.isfinite(final))),
    }
