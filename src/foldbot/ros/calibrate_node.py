"""The calibration node: `foldbot ros-calibrate`'s run on a running cell, through what a real
cell serves: the arm's FollowJointTrajectory action and /joint_states, the colour camera's image
and camera_info. It plans every move on a kinematic twin of the arm (IK, the table checked along
the way, ruckig's time parametrisation), holds the board at each view, reads the board's corners
and the joints at the frame, solves for world → camera and writes the calibration into the
staging folder it is given (`foldbot ros-calibrate` moves it into place). Nothing of the cell's
own is read: not /tf_static, nor anything of the simulated cell's.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path

import numpy as np
import rospy
from sensor_msgs.msg import CameraInfo, Image

from foldbot.calibration.board import CalibrationBoard
from foldbot.calibration.capture import (
    VIEW_WORDS,
    CalibrationCell,
    capture_views,
    plan_views,
    pose_matrix,
    solve_captures,
    write_calibration,
)
from foldbot.calibration.views import BoardMount, CalibrationView
from foldbot.control.executor import ArmExecutor
from foldbot.errors import FoldbotError
from foldbot.operator import OperatorGate
from foldbot.ros import TOPICS, arm_joint_names, convert, driver_actions
from foldbot.ros.drivers import ActionArm
from foldbot.sim.calibration_board import board_twin
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimConfig, SimWorld

SETTLE_S = 0.5
"""Rest after each move before the frame is taken (s, the cell's clock)."""
CAMERA_WAIT_S = 30.0
"""How long (wall s) the node waits for the camera's first image and camera_info, or a frame."""
MOVE_TIMEOUT_S = 60.0
"""How long (wall s) one move may take to be answered."""


class RosCalibrationCell(CalibrationCell):
    """A running cell over ROS: the arm through its driver's action (arm `arm` of `arms`: its
    prefixed joints and namespaced action), the camera's topics."""

    def __init__(
        self,
        robot: str,
        layout,
        arms: int = 1,
        arm: int = 0,
        speed_scale: float = 1.0,
        board: CalibrationBoard | None = None,
        mount: BoardMount | None = None,
    ) -> None:
        self.model_world = SimWorld(SimConfig(layout=layout))
        self.model = make_robot(robot, self.model_world.client, layout.arm_layouts(arms)[arm])
        self.planner = ArmExecutor(
            self.model_world, self.model, None,  # type: ignore[arg-type]  # no grasps: moves only
            model_table_id=self.model_world.table_id, speed_scale=speed_scale,
        )  # fmt: skip
        if board is not None and mount is not None:  # its plate kept clear of obstacles too
            self.planner.carry_body(
                "the board", board_twin(self.model_world.client, board), mount.T_tcp_board()
            )
        self.joint_names = arm_joint_names(self.model.ARM_JOINT_NAMES, arms)[arm]
        self.arm_index = arm
        self.arm = ActionArm(
            self.joint_names, failure=lambda: None, actions=driver_actions(arms)[arm]
        )
        self._lock = threading.Lock()
        self._image: Image | None = None
        self._info: CameraInfo | None = None
        rospy.Subscriber(TOPICS["color"], Image, self._on_image, queue_size=2, buff_size=2**24)
        rospy.Subscriber(TOPICS["color_info"], CameraInfo, self._on_info, queue_size=2)
        self.arm.wait_for_servers()
        self.q_start = self.arm.joint_positions()
        self._wait_for(lambda: self._image is not None and self._info is not None, "the camera")

    def _on_image(self, msg: Image) -> None:
        with self._lock:
            self._image = msg

    def _on_info(self, msg: CameraInfo) -> None:
        with self._lock:
            self._info = msg

    def _wait_for(self, ready, what: str) -> None:
        deadline = time.monotonic() + CAMERA_WAIT_S
        while not ready():
            if time.monotonic() > deadline or rospy.is_shutdown():
                raise FoldbotError(
                    f"nothing from {what} within {CAMERA_WAIT_S:g} s (colour image on "
                    f"{rospy.resolve_name(TOPICS['color'])}, its camera_info on "
                    f"{rospy.resolve_name(TOPICS['color_info'])})"
                )
            time.sleep(0.01)

    def intrinsics(self) -> tuple[np.ndarray, np.ndarray, int, int]:
        with self._lock:
            info = self._info
        assert info is not None
        dist = np.asarray(info.D, dtype=float) if len(info.D) else np.zeros(5)
        return np.array(info.K, dtype=float).reshape(3, 3), dist, info.width, info.height

    def _move(self, q: np.ndarray, name: str, label: str, what: str) -> None:
        q0 = self.arm.joint_positions()
        self.planner.check_joint_move(q0, q)
        traj = self.planner.joint_move_trajectory(q0, q)
        self.confirm_move(label, what, traj.duration)
        self.arm.follow(  # a slowed arm's move (--speed-scale) gets its own time too
            self.joint_names,
            traj.times,
            traj.positions,
            traj.velocities,
            name,
            MOVE_TIMEOUT_S + traj.duration,
        )
        until = rospy.get_time() + SETTLE_S
        deadline = time.monotonic() + SETTLE_S + CAMERA_WAIT_S
        while rospy.get_time() < until:
            if time.monotonic() > deadline or rospy.is_shutdown():
                raise FoldbotError("the cell's clock stopped while the arm settled")
            time.sleep(0.01)

    def rest_positions(self) -> tuple[np.ndarray, np.ndarray]:
        return self.arm.joint_positions(), np.asarray(self.q_start, dtype=float)

    def move_to(self, view: CalibrationView) -> None:
        q0 = self.arm.joint_positions()
        q = self.model.solve_ik(view.position, view.quaternion, q_seed=q0)
        self._move(q, view.name, view.name, VIEW_WORDS)

    def frame(self) -> tuple[np.ndarray, np.ndarray]:
        since = rospy.get_time()

        def fresh() -> bool:
            with self._lock:
                return self._image is not None and self._image.header.stamp.to_sec() >= since

        self._wait_for(fresh, "the camera (a frame after the arm came to rest)")
        with self._lock:
            image = self._image
        assert image is not None
        stamp = image.header.stamp.to_sec()
        q = self.arm.joints_after(stamp, CAMERA_WAIT_S)
        return convert.color_array(image), pose_matrix(*self.model.fk_tcp(q))

    def finish(self) -> None:
        self._move(self.q_start, "back to the start", "back", "joint move back to where it started")

    def close(self) -> None:
        self.model_world.close()


def main(argv: list[str] | None = None) -> int:
    from foldbot.commands.calibrate import add_board_arguments, plan_from_args, write_view_plan

    parser = argparse.ArgumentParser(prog="foldbot_calibrate")
    parser.add_argument("--stage", type=Path, required=True)
    add_board_arguments(parser)
    args = parser.parse_args(rospy.myargv(argv if argv is not None else sys.argv)[1:])
    rospy.init_node("foldbot_calibrate", disable_signals=True)
    try:
        plan = plan_from_args(args)
        board = plan.board
        cell = RosCalibrationCell(
            args.robot, plan.layout, args.arms, plan.arm, plan.speed_scale, board, plan.mount
        )
        gate = OperatorGate(task="the calibration") if args.confirm else None
        cell.gate = gate
        if args.dry_run:  # every view planned from where the arm stands; nothing moves
            try:
                planned = plan_views(
                    cell,
                    plan.views,
                    lambda line: print(f"ros-calibrate: dry run: {line}", flush=True),
                )
            finally:
                cell.close()
            write_view_plan(args.stage, planned, {"cell": "ros", **plan.record()})
            return 0 if planned["feasible"] else 1
        try:
            captures = capture_views(
                cell, plan.views, board, lambda line: print(f"ros-calibrate: {line}", flush=True)
            )
            K, dist, _, _ = cell.intrinsics()
            solution = solve_captures(captures, board, K, dist)
        finally:
            cell.close()
        extra = {} if gate is None else {"operator": gate.record()}
        write_calibration(
            args.stage,
            captures,
            solution,
            board,
            K,
            dist,
            {"cell": "ros", **plan.record(), **extra},
        )
    except FoldbotError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        return 2
    finally:
        rospy.signal_shutdown("calibration done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
