"""The planner node: perceived corners (cloth/keypoints) → fold plan (planning.recipes), or a
garment's perceived keypoints → its whole plan (planning.garment_recipes) → joint trajectories
(IK on every waypoint, ruckig time law: control.executor), on request.

It keeps its own kinematic model of the cell (the same URDF in a private, never-stepped PyBullet
world) for IK; it sees no cloth. Requests and responses are JSON on planner/request and
planner/response (kinds: stage, garment, action, together, lift, time, time_together, park); a
response echoes the request's id and, for motions, carries each step's sampled trajectory and
gripper event.

In a two-arm cell a motion request names its arm (`arm`, 0 = left) and carries every arm's
joints (`qs`): an arm's motion is checked to keep clear of the others where they stand, and a
pair planned `together` is checked at every instant both arms will pass through
(control.bimanual), as the in-process cell does."""

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

from foldbot.control.bimanual import check_arms_clear, check_clear_of_still_arms
from foldbot.control.executor import ArmExecutor, PlannedSegment, check_arm_fits
from foldbot.control.trajectory import JointTrajectory
from foldbot.errors import FoldbotError, UnreachableTargetError, failed_segment
from foldbot.planning.actions import FoldAction
from foldbot.planning.garment_recipes import plan_garment
from foldbot.planning.motion import action_segments
from foldbot.planning.recipes import plan_stage, predicted_outline
from foldbot.planning.spread import action_from_dict, motion_segments
from foldbot.ros import TOPICS, arm_joint_names, convert
from foldbot.ros.node_args import FOLD_ARGS_PARAM, parse_fold_args
from foldbot.ros.publish import publish_when_heard
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld

REQUEST_KINDS = (
    "stage",
    "garment",
    "action",
    "together",
    "lift",
    "time",
    "time_together",
    "park",
    "tracking",
)
"""What the planner node answers (MotionPlanner.handle)."""


def stack_held(trajs: list[JointTrajectory]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Several arms' trajectories (one physics-step sampling) as one: (times, positions,
    velocities) with the arms' joints side by side; an arm whose trajectory ends first holds its
    last sample at rest, as control.executor's run_together and move_joints_together move them."""
    n = max(len(t.times) for t in trajs)
    pos, vel = [], []
    for t in trajs:
        pad = n - len(t.times)
        pos.append(np.vstack([t.positions, np.repeat(t.positions[-1:], pad, axis=0)]))
        vel.append(np.vstack([t.velocities, np.zeros((pad, t.velocities.shape[1]))]))
    longest = max(trajs, key=lambda t: len(t.times))
    return longest.times.copy(), np.hstack(pos), np.hstack(vel)


def _step_dict(ps: PlannedSegment) -> dict:
    return {
        "name": ps.segment.name,
        "gripper": ps.segment.gripper,
        "path": ps.joint_path.tolist(),
        "points": ps.points.tolist(),
        "speed": ps.segment.speed,
        "dwell": ps.segment.dwell,
    }


class MotionPlanner:
    """Plans fold stages and arm motions on a kinematic model of the cell (no ROS inside)."""

    def __init__(self, fold_args: str) -> None:
        _args, self.cfg = parse_fold_args(fold_args)
        self.world = SimWorld(self.cfg.sim)  # the model: table and arms only, never stepped
        self.robots = [
            make_robot(self.cfg.robot, self.world.client, lay)
            for lay in self.world.layout.arm_layouts(self.cfg.arms)
        ]
        self.executors = [
            ArmExecutor(self.world, r, grasp=None, speed_scale=self.cfg.motion.speed_scale)
            for r in self.robots
        ]
        try:  # out of reach, or an obstacle where an arm rests: refused by name
            for ex in self.executors:
                check_arm_fits(ex, self.cfg.robot, self.cfg.park)
        except FoldbotError:
            self.world.close()
            raise
        self.robot, self.executor = self.robots[0], self.executors[0]
        self.joint_names = arm_joint_names(self.robot.ARM_JOINT_NAMES, self.cfg.arms)
        """Each arm's joint names over topics (prefixed in a two-arm cell)."""

    def _arm(self, req: dict) -> int:
        arm = req.get("arm", 0)
        if not (isinstance(arm, int) and 0 <= arm < len(self.robots)):
            raise FoldbotError(f"arm must be in 0–{len(self.robots) - 1}, got {arm!r}")
        return arm

    def _qs(self, req: dict) -> list[np.ndarray]:
        """Every arm's joints (`qs`; a one-arm request may give only `q`)."""
        qs = req.get("qs") or ([req["q"]] if "q" in req else None)
        if qs is None:
            raise FoldbotError(f"a {req.get('kind')} request needs the arms' joints (qs, or q)")
        if len(qs) != len(self.robots):
            raise FoldbotError(f"qs must give {len(self.robots)} arms' joints, got {len(qs)}")
        return [np.array(q, dtype=float) for q in qs]

    def _plan(self, arm: int, segments, q: np.ndarray) -> list[PlannedSegment]:
        """IK for every waypoint of every segment (nothing moves before all are feasible)."""
        self.robots[arm].reset_joints(q)  # the model starts where the arm is, as in process
        return self.executors[arm].plan(segments, q_start=q)

    def _trajectory(self, name: str, traj: JointTrajectory, arm: int = 0) -> dict:
        return {
            "name": name,
            "joint_names": self.joint_names[arm],
            "times": traj.times.tolist(),
            "positions": traj.positions.tolist(),
            "velocities": traj.velocities.tolist(),
        }

    def _stacked(self, name: str, arms: list[int], trajs: list[JointTrajectory]) -> dict:
        times, pos, vel = stack_held(trajs)
        return {
            "name": name,
            "joint_names": [n for arm in arms for n in self.joint_names[arm]],
            "times": times.tolist(),
            "positions": pos.tolist(),
            "velocities": vel.tolist(),
        }

    def _timed(self, step: dict) -> JointTrajectory:
        """A step's trajectory, then still for its dwell (a spread's hang), as in process."""
        executor = self.executors[self._arm(step)]
        traj = executor.trajectory_for(
            np.array(step["path"], dtype=float),
            np.array(step["points"], dtype=float),
            float(step["speed"]),
        )
        dwell = step.get("dwell", 0.0)
        if isinstance(dwell, bool) or not isinstance(dwell, int | float):
            raise FoldbotError(f"a step's dwell must be a number of seconds, got {dwell!r}")
        return traj.held(float(dwell), executor.world.time_step)

    def handle(self, req: dict) -> dict:
        """One request → its response payload (raises FoldbotError on bad or infeasible ones).

        stage: corners → fold plan; garment: a garment's keypoints → its plan, every stage;
        action / lift: joint paths (IK) of the motion's steps, for the request's `arm`;
        together: several (arm, action) pairs' steps, the arms checked to keep clear at every
        instant (ArmsWouldCollideError);
        time: a step's joint path, starting where the arm now is → its trajectory (ruckig);
        time_together: several arms' steps → one trajectory moving them on one clock;
        park: the joint-space trajectory of every arm to its park pose (home or out of view, as
        the episode says);
        tracking: an arm's commanded and measured joints (a trajectory driver's feedback) → the
        distance between the TCPs they put the tool at, per sample and the largest (m)."""
        kind = req.get("kind")
        if kind not in REQUEST_KINDS:
            raise FoldbotError(
                f"unknown planner request kind {kind!r}; allowed: {', '.join(REQUEST_KINDS)}"
            )
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
            arm = self._arm(req)
            return {"trajectory": self._trajectory(req.get("name", ""), self._timed(req), arm)}
        if kind == "tracking":
            arm = self._arm(req)
            desired = np.array(req["desired"], dtype=float).reshape(-1, self.robots[arm].dof)
            actual = np.array(req["actual"], dtype=float).reshape(-1, self.robots[arm].dof)
            if desired.shape != actual.shape:
                raise FoldbotError(
                    f"tracking needs as many measured joints as commanded, got "
                    f"{len(actual)} and {len(desired)}"
                )
            fk = self.robots[arm].fk_tcp
            errors = [
                float(np.linalg.norm(fk(a)[0] - fk(d)[0]))
                for d, a in zip(desired, actual, strict=True)
            ]
            return {"errors": errors, "max_tracking_error": max(errors, default=0.0)}
        if kind == "time_together":
            arms = [self._arm(step) for step in req["steps"]]
            if arms != sorted(set(arms)):
                raise FoldbotError(f"time_together needs distinct arms in order, got {arms}")
            trajs = [self._timed(step) for step in req["steps"]]
            return {"trajectory": self._stacked(req.get("name", ""), arms, trajs)}
        qs = self._qs(req)
        if kind == "together":
            # Pick-and-places, or a spread's two parts (a crumpled towel in the two-arm cell).
            pairs = [(self._arm(p), action_from_dict(p["action"])) for p in req["pairs"]]
            plans = [
                self._plan(
                    arm,
                    motion_segments(action, self.robots[arm].fk_tcp(qs[arm])[0], self.cfg.motion),
                    qs[arm],
                )
                for arm, action in pairs
            ]
            check_arms_clear(
                [(self.executors[arm], plan) for (arm, _), plan in zip(pairs, plans, strict=True)]
            )
            return {"steps": [[_step_dict(ps) for ps in plan] for plan in plans]}
        if kind == "park":
            arms, trajs = [], []
            for arm, (robot, q) in enumerate(zip(self.robots, qs, strict=True)):
                park = robot.out_of_view_q if self.cfg.park == "out_of_view" else robot.home_q
                if np.abs(park - q).max() >= 1e-4:
                    ex = self.executors[arm]
                    try:  # clear of the layout's obstacles (as SimCell.park)
                        ex.check_joint_move(q, park, table=False)
                    except UnreachableTargetError as exc:
                        raise UnreachableTargetError(
                            f"park of arm {arm}: joint move: {exc}"
                        ) from exc
                    arms.append(arm)
                    trajs.append(ex.joint_move_trajectory(q, park))
            if not arms:
                return {"trajectory": None}
            return {"trajectory": self._stacked("park", arms, trajs)}
        arm = self._arm(req)
        q = np.array(req["q"], dtype=float) if "q" in req else qs[arm]
        start, quat = self.robots[arm].fk_tcp(q)
        if kind == "action":
            action = FoldAction.from_dict(req["action"])
            plan = self._plan(arm, action_segments(action, start, self.cfg.motion), q)
            # The other arms wait where they are (as SimCell): the moving one must clear them.
            still = [(self.executors[i], q) for i, q in enumerate(qs) if i != arm]
            check_clear_of_still_arms(arm, (self.executors[arm], plan), still)
            return {"steps": [_step_dict(ps) for ps in plan]}
        if kind == "lift":
            height = float(req.get("height", self.cfg.motion.retreat_height))
            lift = self.executors[arm].lift_segment(start, quat, height, self.cfg.motion.free_speed)
            plan = self._plan(arm, [lift], q)
            return {"steps": [_step_dict(ps) for ps in plan]}
        raise AssertionError(kind)  # unreachable: REQUEST_KINDS is checked first


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
                # The segment an infeasible motion failed in: the task node's flattening tells
                # a failure that another hang margin cannot fix by it (errors.failed_segment).
                "segment": failed_segment(exc),
            }
        try:  # the task subscribed before it asked, but its connection to this node may lag
            publish_when_heard(self.pub, String(data=json.dumps(out)), self.wait_s)
        except FoldbotError as exc:
            rospy.logerr("planner reply %s not sent: %s", req.get("id"), exc)


def main(argv: list[str] | None = None) -> int:
    rospy.init_node("foldbot_planner", argv=argv if argv is not None else sys.argv)
    node = PlannerNode(rospy.get_param(FOLD_ARGS_PARAM))
    rospy.spin()
    node.planner.world.close()
    return 0
