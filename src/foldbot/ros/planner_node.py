"""The planner node: perceived corners (cloth/keypoints) → fold plan (planning.recipes), or a
garment's perceived keypoints → its whole plan (planning.garment_recipes) → joint trajectories
(IK on every waypoint, ruckig time law: control.executor), on request.

It keeps its own kinematic model of the cell (the same URDF in a private, never-stepped PyBullet
world) for IK; it sees no cloth. Requests and responses are JSON on planner/request and
planner/response (kinds: stage, garment, action, lift, time, park); a response echoes the
request's id and, for motions, carries each step's sampled trajectory and gripper event."""

from __future__ import annotations

import json
import sys
import threading
import time
from collections import OrderedDict

import numpy as np
import rospy
from geometry_msgs.msg import PoseArray
from std_msgs.msg import String

from foldbot.control.executor import ArmExecutor
from foldbot.errors import FoldbotError
from foldbot.planning.actions import FoldAction
from foldbot.planning.garment_recipes import plan_garment
from foldbot.planning.motion import Segment, action_segments, line_path
from foldbot.planning.recipes import plan_stage, predicted_outline
from foldbot.ros import TOPICS, convert
from foldbot.ros.node_args import FOLD_ARGS_PARAM, parse_fold_args
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld


class MotionPlanner:
    """Plans fold stages and arm motions on a kinematic model of the cell (no ROS inside)."""

    def __init__(self, fold_args: str) -> None:
        _args, self.cfg = parse_fold_args(fold_args)
        self.world = SimWorld(self.cfg.sim)  # the model: table and arm only, never stepped
        self.robot = make_robot(self.cfg.robot, self.world.client, self.world.layout)
        self.executor = ArmExecutor(self.world, self.robot, grasp=None)

    def _ik_steps(self, segments, q: np.ndarray) -> list[dict]:
        """IK for every waypoint of every segment (nothing moves before all are feasible)."""
        self.robot.reset_joints(q)  # the model starts where the arm is, as in-process planning
        return [
            {
                "name": ps.segment.name,
                "gripper": ps.segment.gripper,
                "path": ps.joint_path.tolist(),
                "points": ps.points.tolist(),
                "speed": ps.segment.speed,
            }
            for ps in self.executor.plan(segments, q_start=q)
        ]

    def _trajectory(self, name: str, traj) -> dict:
        return {
            "name": name,
            "joint_names": list(self.robot.ARM_JOINT_NAMES),
            "times": traj.times.tolist(),
            "positions": traj.positions.tolist(),
            "velocities": traj.velocities.tolist(),
        }

    def handle(self, req: dict) -> dict:
        """One request → its response payload (raises FoldbotError on bad or infeasible ones).

        stage: corners → fold plan; garment: a garment's keypoints → its plan, every stage;
        action / lift: joint paths (IK) of the motion's steps;
        time: a step's joint path, starting where the arm now is → its trajectory (ruckig);
        park: the joint-space trajectory to the park pose (home or out of view, as the episode
        says)."""
        kind = req.get("kind")
        if kind == "stage":
            corners = {k: np.array(v, dtype=float) for k, v in req["corners"].items()}
            room = float(req.get("crease_room", 0.0))
            plan = plan_stage(
                req["recipe"], int(req["stage"]), corners, float(req["place_lift"]), room
            )
            outline = predicted_outline(req["recipe"], int(req["stage"]), corners, room)
            return {
                "fold_lines": [list(line) for line in plan.fold_lines],
                "actions": [a.as_dict() for a in plan.actions],
                "predicted_outline": np.asarray(outline).tolist(),
            }
        if kind == "garment":
            keypoints = {k: np.array(v, dtype=float) for k, v in req["keypoints"].items()}
            plan = plan_garment(
                req["recipe"], keypoints, float(req["place_lift"]), float(req["thickness"])
            )
            return {"plan": plan.as_dict()}
        if kind == "time":
            traj = self.executor.trajectory_for(
                np.array(req["path"], dtype=float),
                np.array(req["points"], dtype=float),
                float(req["speed"]),
            )
            return {"trajectory": self._trajectory(req.get("name", ""), traj)}
        q = np.array(req["q"], dtype=float)
        start = self.robot.fk_tcp(q)[0]
        if kind == "action":
            action = FoldAction.from_dict(req["action"])
            return {"steps": self._ik_steps(action_segments(action, start, self.cfg.motion), q)}
        if kind == "lift":
            up = start + [0.0, 0.0, float(req.get("height", self.cfg.motion.retreat_height))]
            return {
                "steps": self._ik_steps(
                    [Segment("lift", line_path(start, up), self.cfg.motion.free_speed)], q
                )
            }
        if kind == "park":
            park = self.robot.out_of_view_q if self.cfg.park == "out_of_view" else self.robot.home_q
            if np.abs(park - q).max() < 1e-4:
                return {"trajectory": None}
            traj = self.executor.joint_move_trajectory(q, park)
            return {"trajectory": self._trajectory("park", traj)}
        raise FoldbotError(
            f"unknown planner request kind {kind!r}; allowed: stage, garment, action, lift, time, "
            "park"
        )


class PlannerNode:
    """MotionPlanner on topics; a stage is planned from the perceived corners on cloth/keypoints
    (the frame named by the request's `keypoints_stamp`) or from corners the request carries."""

    def __init__(self, fold_args: str, wait_s: float = 60.0) -> None:
        self.planner = MotionPlanner(fold_args)
        self.wait_s = wait_s
        self.keypoints: OrderedDict[float, PoseArray] = OrderedDict()
        self.arrived = threading.Condition()
        self.pub = rospy.Publisher(TOPICS["plan_response"], String, queue_size=10)
        rospy.Subscriber(TOPICS["keypoints"], PoseArray, self._on_keypoints, queue_size=100)
        rospy.Subscriber(TOPICS["plan_request"], String, self._on_request)

    def _on_keypoints(self, msg: PoseArray) -> None:
        with self.arrived:
            self.keypoints[round(msg.header.stamp.to_sec(), 6)] = msg
            while len(self.keypoints) > 64:
                self.keypoints.popitem(last=False)
            self.arrived.notify_all()

    def perceived_corners(self, stamp: float) -> dict[str, list[float]]:
        """The corners perception published for the frame at `stamp`."""
        key, deadline = round(stamp, 6), time.monotonic() + self.wait_s
        with self.arrived:
            while key not in self.keypoints:
                if time.monotonic() > deadline or rospy.is_shutdown():
                    raise FoldbotError(f"no cloth/keypoints for the frame at t = {stamp:.3f} s")
                self.arrived.wait(0.5)
            msg = self.keypoints[key]
        return {k: v.tolist() for k, v in convert.corners_of_pose_array(msg).items()}

    def _on_request(self, msg: String) -> None:
        req = json.loads(msg.data)
        try:
            if req.get("kind") == "stage" and "keypoints_stamp" in req:
                req["corners"] = self.perceived_corners(float(req["keypoints_stamp"]))
            out = {"id": req.get("id"), "ok": True, **self.planner.handle(req)}
        except FoldbotError as exc:
            out = {
                "id": req.get("id"),
                "ok": False,
                "error": str(exc),
                "error_type": type(exc).__name__,
            }
        self.pub.publish(String(data=json.dumps(out)))


def main(argv: list[str] | None = None) -> int:
    rospy.init_node("foldbot_planner", argv=argv if argv is not None else sys.argv)
    node = PlannerNode(rospy.get_param(FOLD_ARGS_PARAM))
    rospy.spin()
    node.planner.world.close()
    return 0
