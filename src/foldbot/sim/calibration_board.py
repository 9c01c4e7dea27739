"""A calibration board fixed to the simulated arm's tool, for hand–eye calibration: a white plate
and what is printed black on it (squares, and a ChArUco board's markers) as one rigid body (visual shapes only: it touches nothing), held on the TCP
link by a fixed constraint as a bracket holds a printed board."""

from __future__ import annotations

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import CalibrationBoard
from foldbot.calibration.views import BoardMount
from foldbot.errors import require

PLATE_THICKNESS = 0.004
"""The plate's thickness (m), behind its printed face."""
PRINT_THICKNESS = 0.0004
"""The black print stands this proud of the plate's face (m)."""
MAX_PRINT_PIECES = 127
"""Black boxes one board body holds: PyBullet keeps at most 128 links on a multibody and drops
the rest unsaid (the plate is one)."""
BOARD_MASS = 0.05
"""The board and its bracket (kg)."""


def board_twin(client: int, board: CalibrationBoard) -> int:
    """The board's plate as a static box in a planning world (`client`: a kinematic twin's,
    never stepped), for ArmExecutor.carry_body to keep clear of a layout's obstacles; its base
    frame is the board frame."""
    x0, x1, y0, y1 = board.plate_bounds()
    shape = p.createCollisionShape(
        p.GEOM_BOX,
        halfExtents=[(x1 - x0) / 2.0, (y1 - y0) / 2.0, PLATE_THICKNESS / 2.0],
        collisionFramePosition=[(x0 + x1) / 2.0, (y0 + y1) / 2.0, PLATE_THICKNESS / 2.0],
        physicsClientId=client,
    )
    return p.createMultiBody(0.0, shape, -1, physicsClientId=client)


def attach_board(robot, board: CalibrationBoard, mount: BoardMount) -> int:
    """Build `board` in the robot's PyBullet client and fix it to the robot's TCP as `mount`
    says; returns the board's body id. Its base frame is the board frame (calibration.board)."""
    client = robot.client
    x0, x1, y0, y1 = board.plate_bounds()
    plate = p.createVisualShape(
        p.GEOM_BOX,
        halfExtents=[(x1 - x0) / 2.0, (y1 - y0) / 2.0, PLATE_THICKNESS / 2.0],
        visualFramePosition=[(x0 + x1) / 2.0, (y0 + y1) / 2.0, PLATE_THICKNESS / 2.0],
        rgbaColor=[1.0, 1.0, 1.0, 1.0],
        specularColor=[0.0, 0.0, 0.0],
        physicsClientId=client,
    )
    # The plate's box as its collision shape gives the body its inertia (none would leave it
    # without, and the constraint's solve would divide by it); it is then kept from touching
    # anything.
    plate_shape = p.createCollisionShape(
        p.GEOM_BOX,
        halfExtents=[(x1 - x0) / 2.0, (y1 - y0) / 2.0, PLATE_THICKNESS / 2.0],
        collisionFramePosition=[(x0 + x1) / 2.0, (y0 + y1) / 2.0, PLATE_THICKNESS / 2.0],
        physicsClientId=client,
    )
    shapes: dict[tuple[float, float], int] = {}  # one visual shape per rectangle size

    def shape(w: float, h: float) -> int:
        key = (round(w, 9), round(h, 9))
        if key not in shapes:
            shapes[key] = p.createVisualShape(
                p.GEOM_BOX,
                halfExtents=[w / 2.0, h / 2.0, PRINT_THICKNESS / 2.0],
                rgbaColor=[0.02, 0.02, 0.02, 1.0],
                specularColor=[0.0, 0.0, 0.0],
                physicsClientId=client,
            )
        return shapes[key]

    rects = board.black_rects()
    require(
        len(rects) <= MAX_PRINT_PIECES,
        f"the simulated board prints in boxes, at most {MAX_PRINT_PIECES} (PyBullet's links "
        f"on one body); this {board.squares_x} × {board.squares_y} {board.pattern} needs "
        f"{len(rects)}: fewer squares, or a ChArUco board's markers from a smaller dictionary",
    )
    black = [((a0 + a1) / 2.0, (b0 + b1) / 2.0) for a0, a1, b0, b1 in rects]
    visuals = [shape(a1 - a0, b1 - b0) for a0, a1, b0, b1 in rects]
    n = len(black)
    T_tcp_board = mount.T_tcp_board()
    tcp_pos, tcp_quat = robot.tcp_pose()
    R_tcp = Rotation.from_quat(tcp_quat)
    pos = np.asarray(tcp_pos) + R_tcp.apply(T_tcp_board[:3, 3])
    quat = (R_tcp * Rotation.from_matrix(T_tcp_board[:3, :3])).as_quat()
    body = p.createMultiBody(
        baseMass=BOARD_MASS,
        baseCollisionShapeIndex=plate_shape,
        baseVisualShapeIndex=plate,
        basePosition=pos.tolist(),
        baseOrientation=quat.tolist(),
        linkMasses=[0.0] * n,
        linkCollisionShapeIndices=[-1] * n,
        linkVisualShapeIndices=visuals,
        linkPositions=[[x, y, -PRINT_THICKNESS / 2.0] for x, y in black],
        linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n,
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
        linkParentIndices=[0] * n,
        linkJointTypes=[p.JOINT_FIXED] * n,
        linkJointAxis=[[0.0, 0.0, 1.0]] * n,
        physicsClientId=client,
    )
    for link in range(-1, n):
        p.setCollisionFilterGroupMask(body, link, 0, 0, physicsClientId=client)
    mount_quat = Rotation.from_matrix(T_tcp_board[:3, :3]).as_quat()
    constraint = p.createConstraint(
        robot.body_id,
        robot.tcp_link_index,
        body,
        -1,
        p.JOINT_FIXED,
        [0.0, 0.0, 0.0],
        parentFramePosition=T_tcp_board[:3, 3].tolist(),
        childFramePosition=[0.0, 0.0, 0.0],
        parentFrameOrientation=mount_quat.tolist(),
        physicsClientId=client,
    )
    p.changeConstraint(constraint, maxForce=500.0, physicsClientId=client)
    return body
