"""Generate ur5_gripper.urdf and ur5e_gripper.urdf: a Universal Robots arm on its standard DH
frames (the UR5, CB3, and the UR5e, e-Series), plus foldbot's parallel-jaw gripper.

Run from the repository root:  python src/foldbot/sim/robots/urdf/make_ur_urdf.py

Frames
- Root link `base_link` is ur_description's `base_link`: at q = 0 the arm stretches along its +x.
  The DH base frame (the UR controller's "base", ur_description's `base`) is `base_link` turned
  by π about z; `shoulder_pan_joint` sits on it (origin rpy = 0 0 π), so
  pose_in_base_link = Rz(π) · DH_FK(q).
- Link i (1..6) frame = DH frame i-1 turned by q_i about its z axis. Joint i+1 sits at
  Tz(d_i)·Tx(a_i)·Rx(α_i) in link i, i.e. on DH frame i, so chaining the URDF reproduces the DH
  forward kinematics exactly. `flange` (= `tool0`, DH frame 6) is fixed at Tz(d6) on `wrist_3_link`.
- Gripper (flange frame: z out of the flange = approach, y = closing axis):
  coupling + palm z ∈ [0, 0.06]; fingers hang from z = 0.06 to the fingertips at z = 0.11.
  Each finger is a 0.02 (x) × 0.01 (y) × 0.05 (z) m box, 0.05 kg. Finger joints are prismatic,
  q ∈ [0, 0.039] m; the left finger (+y side) opens along +y, the right along −y. Each finger
  link frame lies on its inner (gripping) face; at q = 0 the faces sit at y = ±0.001, so the gap is
  0.002 + q_left + q_right (2 mm closed, 80 mm fully open).
- `tcp` is fixed at z = 0.105 on the flange (centred between the fingers, 5 mm above the tips),
  with the flange's axes: z = approach, y = finger closing axis.

Dynamics: link masses and centres of mass from Universal Robots' published DH/dynamics
parameters of each model (as in ur_description; UR publishes the UR5's centres of mass for the
UR5e too), inertias as solid cylinders like ur_description's cylinder_inertial; limits: ±2π
(elbow ±π, ur_description's limited variant), 3.15 rad/s (UR5) or π rad/s (UR5e),
150/150/150/28/28/28 N·m. The links' collision cylinders follow each model's offsets (the
upper arm's shoulder offset, the forearm's, the wrists' d4–d6); they are what the planner keeps
off the table and the obstacles, not the housings' exact shapes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ALPHA = [math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0]

JOINT_NAMES = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]
LINK_NAMES = [
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
]
LOWER = [-2 * math.pi, -2 * math.pi, -math.pi, -2 * math.pi, -2 * math.pi, -2 * math.pi]
UPPER = [2 * math.pi, 2 * math.pi, math.pi, 2 * math.pi, 2 * math.pi, 2 * math.pi]
EFFORT = [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]
# Centres of mass in DH frame i (m): Universal Robots' UR5 dynamics parameters, which UR's DH
# page gives for the UR5e as well.
COM = [
    (0.0, -0.02561, 0.00193),
    (0.2125, 0.0, 0.11336),
    (0.15, 0.0, 0.0265),
    (0.0, -0.0018, 0.01634),
    (0.0, 0.0018, 0.01634),
    (0.0, 0.0, -0.001159),
]
# Solid-cylinder inertia approximation (radius, length, axis in DH frame i), after ur_description.
INERTIA_CYL = [
    (0.06, 0.15, "y"),
    (0.06, 0.56, "x"),
    (0.06, 0.5, "x"),
    (0.06, 0.12, "z"),
    (0.06, 0.12, "z"),
    (0.0375, 0.0345, "z"),
]

Shape = tuple[float, float, str, tuple[float, float, float]]
"""A link's collision/visual cylinder in DH frame i: (radius, length, axis, centre)."""


@dataclass(frozen=True)
class URModel:
    """One Universal Robots model: its standard DH lengths, link masses, joint speeds and the
    cylinders its links are drawn and collide as."""

    name: str
    """The robot's registry name; the URDF is written to `<name>_gripper.urdf`."""
    title: str
    d: tuple[float, ...]
    """DH offsets d_i (m)."""
    a: tuple[float, ...]
    """DH lengths a_i (m)."""
    mass: tuple[float, ...]
    """Link masses (kg), shoulder to wrist 3."""
    velocity: float
    """Every joint's top speed (rad/s)."""
    base_height: float
    """Height of the base's drawn cylinder (m), up to the shoulder's housing."""
    shapes: tuple[tuple[Shape, ...], ...]


UR5 = URModel(
    name="ur5",
    title="UR5 (CB3)",
    d=(0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823),
    a=(0.0, -0.425, -0.39225, 0.0, 0.0, 0.0),
    mass=(3.7, 8.393, 2.275, 1.219, 1.219, 0.1879),
    velocity=3.15,
    base_height=0.086,
    shapes=(
        ((0.06, 0.10, "y", (0.0, -0.02, 0.0)), (0.06, 0.14, "z", (0.0, 0.0, 0.07))),
        ((0.045, 0.425, "x", (0.2125, 0.0, 0.136)), (0.05, 0.14, "z", (0.0, 0.0, 0.08))),
        ((0.038, 0.39225, "x", (0.196, 0.0, 0.016)), (0.045, 0.12, "z", (0.0, 0.0, 0.06))),
        ((0.045, 0.11, "z", (0.0, 0.0, 0.04)),),
        ((0.045, 0.10, "z", (0.0, 0.0, 0.02)),),
        ((0.0375, 0.024, "z", (0.0, 0.0, -0.012)),),
    ),
)
"""The UR5 (CB3): ur_description's ur5 (shoulder offset 0.136 m, forearm 0.016 m off the DH
line)."""

UR5E = URModel(
    name="ur5e",
    title="UR5e",
    d=(0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996),
    a=(0.0, -0.425, -0.3922, 0.0, 0.0, 0.0),
    mass=(3.761, 8.058, 2.846, 1.37, 1.3, 0.365),
    velocity=math.pi,
    base_height=0.1,
    shapes=(
        ((0.06, 0.10, "y", (0.0, -0.02, 0.0)), (0.06, 0.14, "z", (0.0, 0.0, 0.07))),
        ((0.045, 0.425, "x", (0.2125, 0.0, 0.138)), (0.05, 0.15, "z", (0.0, 0.0, 0.075))),
        ((0.038, 0.3922, "x", (0.1961, 0.0, 0.007)), (0.045, 0.145, "z", (0.0, 0.0, 0.0705))),
        ((0.045, 0.115, "z", (0.0, 0.0, 0.0425)),),
        ((0.045, 0.11, "z", (0.0, 0.0, 0.025)),),
        ((0.0375, 0.024, "z", (0.0, 0.0, -0.012)),),
    ),
)
"""The UR5e: ur_description's ur5e (shoulder offset 0.138 m, elbow offset 0.131 m, so the
forearm runs 7 mm off the DH line; wrists d4 = 0.1333, d5 = 0.0997, d6 = 0.0996 m)."""

MODELS = (UR5, UR5E)
"""Every model this script writes a URDF for."""

BASE_MASS = 4.0
PALM_Z = 0.06
FINGER_SIZE = (0.02, 0.01, 0.05)
FINGER_MASS = 0.05
FINGER_HALF_GAP = 0.001
FINGER_STROKE = 0.039
FINGER_EFFORT = 40.0
FINGER_VELOCITY = 0.1
TCP_Z = PALM_Z + FINGER_SIZE[2] - 0.005
GRIPPER_MASS = 0.5


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def axis_rotation(axis: str) -> np.ndarray:
    """Rotation taking local z (URDF cylinder axis) onto the named axis."""
    if axis == "x":
        return np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # Ry(π/2)
    if axis == "y":
        return rot_x(-math.pi / 2)
    return np.eye(3)


def rpy(r: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(y)·Ry(p)·Rx(r)) of a rotation matrix."""
    pitch = math.asin(-max(-1.0, min(1.0, r[2, 0])))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    else:
        roll = math.atan2(-r[1, 2], r[1, 1])
        yaw = 0.0
    return roll, pitch, yaw


def fmt(v) -> str:
    return " ".join(f"{0.0 if abs(x) < 1e-15 else x:.12g}" for x in v)


def origin(xyz, r: np.ndarray) -> str:
    return f'<origin xyz="{fmt(xyz)}" rpy="{fmt(rpy(r))}"/>'


def cylinder_inertia(m: float, r: float, length: float, axis: str) -> tuple[float, float, float]:
    along = m * r * r / 2
    perp = m * (3 * r * r + length * length) / 12
    return tuple(along if a == axis else perp for a in "xyz")


def inertial(m: float, xyz, r: np.ndarray, diag) -> str:
    ixx, iyy, izz = diag
    return (
        f'    <inertial>\n      {origin(xyz, r)}\n      <mass value="{m:.9g}"/>\n'
        f'      <inertia ixx="{ixx:.9g}" ixy="0" ixz="0" iyy="{iyy:.9g}" iyz="0" '
        f'izz="{izz:.9g}"/>\n'
        "    </inertial>\n"
    )


def shape(kind: str, geom: str, xyz, r: np.ndarray, material: str | None = None) -> str:
    mat = f'\n      <material name="{material}"/>' if material else ""
    return (
        f"    <{kind}>\n      {origin(xyz, r)}\n      <geometry>{geom}</geometry>{mat}\n"
        f"    </{kind}>\n"
    )


def cylinder_pair(radius, length, axis, centre, to_link_r, to_link_t, material) -> str:
    r = to_link_r @ axis_rotation(axis)
    xyz = to_link_r @ np.asarray(centre) + to_link_t
    geom = f'<cylinder radius="{radius}" length="{length}"/>'
    return shape("visual", geom, xyz, r, material) + shape("collision", geom, xyz, r)


def build(model: URModel = UR5) -> str:
    """The URDF text of `model` with foldbot's gripper."""
    out = [
        '<?xml version="1.0"?>',
        "<!-- Generated by make_ur_urdf.py; edit that script, not this file. -->",
        f"<!-- {model.title} on its standard DH frames + parallel-jaw gripper. "
        "Root = ur_description base_link = DH base turned by pi about z. -->",
        f'<robot name="{model.name}_gripper">',
        '  <material name="ur_blue"><color rgba="0.35 0.55 0.75 1"/></material>',
        '  <material name="ur_grey"><color rgba="0.7 0.7 0.7 1"/></material>',
        '  <material name="dark"><color rgba="0.15 0.15 0.15 1"/></material>',
    ]
    eye = np.eye(3)
    base = '  <link name="base_link">\n'
    base += inertial(BASE_MASS, (0, 0, 0), eye, cylinder_inertia(BASE_MASS, 0.06, 0.05, "z"))
    h = model.base_height
    base += cylinder_pair(0.075, h, "z", (0, 0, h / 2), eye, np.zeros(3), "ur_grey")
    base += "  </link>"
    out.append(base)
    parent = "base_link"
    parent_xyz, parent_r = np.zeros(3), np.diag([-1.0, -1.0, 1.0])  # Rz(π): DH base frame
    for i in range(6):
        out.append(
            f'  <joint name="{JOINT_NAMES[i]}" type="revolute">\n'
            f'    <parent link="{parent}"/>\n    <child link="{LINK_NAMES[i]}"/>\n'
            f"    {origin(parent_xyz, parent_r)}\n"
            '    <axis xyz="0 0 1"/>\n'
            f'    <limit lower="{LOWER[i]:.17g}" upper="{UPPER[i]:.17g}" '
            f'effort="{EFFORT[i]:g}" velocity="{model.velocity:g}"/>\n'
            '    <dynamics damping="0.0" friction="0.0"/>\n'
            "  </joint>"
        )
        # DH frame i expressed in link i: Tz(d)·Tx(a)·Rx(α).
        t = np.array([model.a[i], 0.0, model.d[i]])
        r = rot_x(ALPHA[i])
        link = f'  <link name="{LINK_NAMES[i]}">\n'
        rad, length, axis = INERTIA_CYL[i]
        m = model.mass[i]
        link += inertial(m, r @ np.asarray(COM[i]) + t, r, cylinder_inertia(m, rad, length, axis))
        for k, (sr, sl, sa, sc) in enumerate(model.shapes[i]):
            link += cylinder_pair(sr, sl, sa, sc, r, t, "ur_blue" if k == 0 else "ur_grey")
        link += "  </link>"
        out.append(link)
        parent, parent_xyz, parent_r = LINK_NAMES[i], t, r

    out.append(
        '  <joint name="flange_joint" type="fixed">\n    <parent link="wrist_3_link"/>\n'
        f'    <child link="flange"/>\n    {origin(parent_xyz, parent_r)}\n  </joint>\n'
        '  <link name="flange">\n' + inertial(1e-3, (0, 0, 0), eye, (1e-7,) * 3) + "  </link>"
    )
    # Gripper body: coupling disc + palm box, in the flange frame.
    g = '  <link name="gripper_base_link">\n'
    g += inertial(GRIPPER_MASS, (0, 0, 0.035), eye, (6.5e-4, 2.0e-4, 6.5e-4))
    g += shape("visual", '<cylinder radius="0.035" length="0.01"/>', (0, 0, 0.005), eye, "dark")
    g += shape("collision", '<cylinder radius="0.035" length="0.01"/>', (0, 0, 0.005), eye)
    g += shape("visual", '<box size="0.05 0.12 0.05"/>', (0, 0, 0.035), eye, "dark")
    g += shape("collision", '<box size="0.05 0.12 0.05"/>', (0, 0, 0.035), eye)
    g += "  </link>"
    out.append(
        '  <joint name="gripper_mount_joint" type="fixed">\n    <parent link="flange"/>\n'
        '    <child link="gripper_base_link"/>\n    <origin xyz="0 0 0" rpy="0 0 0"/>\n  </joint>'
    )
    out.append(g)
    sx, sy, sz = FINGER_SIZE
    fin = (
        FINGER_MASS * (sy * sy + sz * sz) / 12,
        FINGER_MASS * (sx * sx + sz * sz) / 12,
        FINGER_MASS * (sx * sx + sy * sy) / 12,
    )
    for side, sign in (("left", 1.0), ("right", -1.0)):
        centre = (0.0, sign * sy / 2, sz / 2)
        box = f'<box size="{sx} {sy} {sz}"/>'
        out.append(
            f'  <joint name="{side}_finger_joint" type="prismatic">\n'
            '    <parent link="gripper_base_link"/>\n'
            f'    <child link="{side}_finger_link"/>\n'
            f'    <origin xyz="0 {sign * FINGER_HALF_GAP:g} {PALM_Z}" rpy="0 0 0"/>\n'
            f'    <axis xyz="0 {sign:g} 0"/>\n'
            f'    <limit lower="0" upper="{FINGER_STROKE}" effort="{FINGER_EFFORT:g}" '
            f'velocity="{FINGER_VELOCITY:g}"/>\n'
            "  </joint>"
        )
        out.append(
            f'  <link name="{side}_finger_link">\n'
            "    <contact>\n"
            '      <lateral_friction value="1.5"/>\n'
            '      <spinning_friction value="0.01"/>\n'
            '      <rolling_friction value="0.0"/>\n'
            "    </contact>\n"
            + inertial(FINGER_MASS, centre, eye, fin)
            + shape("visual", box, centre, eye, "ur_grey")
            + shape("collision", box, centre, eye)
            + "  </link>"
        )
    out.append(
        '  <joint name="tcp_joint" type="fixed">\n    <parent link="gripper_base_link"/>\n'
        f'    <child link="tcp"/>\n    <origin xyz="0 0 {TCP_Z:.6g}" rpy="0 0 0"/>\n  </joint>\n'
        '  <link name="tcp">\n' + inertial(1e-3, (0, 0, 0), eye, (1e-7,) * 3) + "  </link>"
    )
    out.append("</robot>\n")
    return "\n".join(out)


def urdf_path(model: URModel) -> Path:
    """Where the URDF of `model` is shipped, beside this script."""
    return Path(__file__).with_name(f"{model.name}_gripper.urdf")


def main() -> None:
    for model in MODELS:
        path = urdf_path(model)
        path.write_text(build(model))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
