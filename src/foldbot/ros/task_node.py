"""The task node: sequences a whole fold on task_cell.RosCell and writes the episode folder.

It runs the same closed loop as `foldbot fold` (foldbot.loop.run_fold), first flattening a
crumpled start (foldbot.flatten), then scores the fold from the sim node's ground truth (metrics
only; a real cell's fold is reported as the camera saw it) and writes the episode output contract:
result.json, cloth.npz, video.mp4 (the camera stream with the debug overlays) and the overlays.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import rospy
from std_msgs.msg import String

from foldbot import errors
from foldbot.dry_run import (
    DryRun,
    check_dry_run_config,
    check_dry_run_output,
    dry_run,
    dry_run_flatten,
    write_dry_run,
)
from foldbot.flatten import flatten_and_score, flatten_pictured
from foldbot.flatten_options import flatten_configs
from foldbot.garment_loop import run_garment_fold
from foldbot.io.episode import EpisodeWriter, to_jsonable
from foldbot.loop import FoldRecord, fold_and_picture, run_fold
from foldbot.metrics import score_episode
from foldbot.operator import OperatorGate
from foldbot.pipeline import (
    EpisodeConfig,
    episode_result,
    first_frame_keypoint_errors,
    fold_fields,
    injected_faults,
    loop_config,
    seeded_garment,
    seeded_pose,
)
from foldbot.ros import TOPICS, convert
from foldbot.ros.node_args import (
    ARM_INTERFACE_PARAM,
    CELL_PARAM,
    CLOTH_THICKNESS_PARAM,
    DRY_RUN_PARAM,
    ERROR_FILE_PARAM,
    FINGER_JOINTS_PARAM,
    FINGER_TRAVEL_PARAM,
    FOLD_ARGS_PARAM,
    GRIPPER_EFFORT_PARAM,
    GRIPPER_LEAD_PARAM,
    GRIPPER_LEAD_S,
    MAX_CLOTH_THICKNESS,
    TOGETHER_LEAD_PARAM,
    TOGETHER_LEAD_S,
    finger_joint_names,
    finger_travel_for,
    parse_fold_args,
)
from foldbot.ros.task_cell import RosCell
from foldbot.sim.robots import robot_class
from foldbot.verdict import perceived_verdict, unscored_outcome


def real_cell_thickness(cfg: EpisodeConfig, given: float | None = None) -> float:
    """The layer height the loop assumes where depth tells nothing, on a real cell: `given` (m,
    the real towel's: `ros-fold --cloth-thickness`), else the simulated cloth's of the same
    size and options (two collision margins, as the sim node publishes it). Where it can, the
    loop measures a laid layer's rise in depth instead."""
    if given is not None:
        if not (math.isfinite(given) and 0.0 < given <= MAX_CLOTH_THICKNESS):
            raise errors.ConfigError(
                f"cloth thickness must be metres in (0, {MAX_CLOTH_THICKNESS:g}], got {given!r}"
            )
        return float(given)
    if cfg.cloth.thickness is not None:
        return float(cfg.cloth.thickness)
    edge = seeded_garment(cfg)[1].edge_length
    return 2.0 * (cfg.cloth.collision_margin or edge / cfg.cloth.margin_divisor)


def perceived_outcome(record: FoldRecord) -> dict:
    """What the camera says of a fold no ground truth scores: each stage's mask IoU with the
    outline its plan predicted (verified at the loop's verify_iou), and the cloth's top-view
    area before and after."""
    first, last = record.initial_state, record.final_state
    start = first.coverage_m2 if first is not None and first.detected else None
    end = last.coverage_m2 if last is not None and last.detected else None
    return {
        "verified": bool(perceived_verdict(record.stages)),
        "stage_mask_iou": [float(s["mask_iou_vs_predicted"]) for s in record.stages],
        "coverage_m2_start": start,
        "coverage_m2_final": end,
        "coverage_ratio": None if not start or end is None else end / start,
    }


def real_cell_result(
    cfg: EpisodeConfig, record: FoldRecord, sim_seconds: float, wall_seconds: float
) -> dict:
    """result.json of a fold on a real cell: the contract's keys, the metrics None (nothing
    measures the cloth's vertices), the perceived outcome beside them."""
    cam = record.final_obs
    return {
        "scored": False,
        "success": None,
        "fold_error_mm": None,
        "normalized_performance": None,
        "coverage": None,
        "perceived": perceived_outcome(record),
        **fold_fields(cfg, record),
        "loop_options": dict(cfg.loop_options),
        "flatten_options": dict(cfg.flatten_options),  # the task's, as the loop's
        "seed": None,
        "perception": cfg.perception,
        "closed_loop": cfg.closed_loop,
        "grasp_points_source": "vision",
        "camera": None
        if cam is None
        else {
            "width": cam.intrinsics.width,
            "height": cam.intrinsics.height,
            "K": np.asarray(cam.intrinsics.K).tolist(),
            "T_world_camera": np.asarray(cam.T_world_camera).tolist(),
        },
        "actions": record.actions,
        "sim_seconds": sim_seconds,
        "wall_seconds": wall_seconds,
    }


def operator_gate(args: argparse.Namespace) -> OperatorGate | None:
    """`--confirm`'s gate on the task node's stdin and stdout (roslaunch hands them down from
    `foldbot ros-fold`, output="screen"), or None."""
    return OperatorGate() if getattr(args, "confirm", False) else None


def run_real_task(
    fold_args: str,
    log=rospy.loginfo,
    gripper_lead: float | None = GRIPPER_LEAD_S,
    together_lead: float = TOGETHER_LEAD_S,
    cloth_thickness: float | None = None,
    finger_joints: str = "",
    finger_travel: float | None = None,
    gripper_effort: float = 0.0,
) -> dict:
    """Fold on a real cell (whatever serves the drivers' actions and the camera) and write the
    episode folder, unscored: result.json, video.mp4 and the overlays; no cloth.npz.
    `cloth_thickness` (m): the towel's layer thickness (None: real_cell_thickness's default).
    `finger_travel`: the slip watch's (None: finger_travel_for's, from that thickness);
    `gripper_effort`: the max_effort (N) of the gripper goals (0: no limit)."""
    args, cfg = parse_fold_args(fold_args)
    thickness = real_cell_thickness(cfg, cloth_thickness)
    finger_travel, travel_from = finger_travel_for(finger_travel, finger_joints, thickness)
    if cfg.perception != "vision":
        raise errors.ConfigError(
            f"a real cell folds with vision perception; got perception {cfg.perception!r}"
        )
    writer = EpisodeWriter(args.out, overwrite=args.overwrite, fps=max(cfg.video_fps, 1.0))
    wall0 = time.perf_counter()
    with writer, contextlib.ExitStack() as stack:
        cell = RosCell(
            cfg.sim.layout,
            writer if cfg.video_fps > 0 else None,
            cfg.arms,
            "actions",
            robot_class(cfg.robot).ARM_JOINT_NAMES,
            cell="real",
            finger_names=finger_joint_names(
                finger_joints, robot_class(cfg.robot).FINGER_JOINT_NAMES
            ),
            finger_travel=finger_travel,
            gripper_lead=gripper_lead,
            together_lead=together_lead,
            gripper_effort=gripper_effort,
        )
        stack.callback(cell.stop_video)
        cell.gate = operator_gate(args)
        cell.wait_for_real_cell()

        def write_image(name: str, image: np.ndarray) -> None:
            with cell._lock:
                writer.write_image(name, image)

        flattened = None
        if cfg.start == "crumpled":  # flattened by what the camera sees, judged by it alone
            spec = seeded_garment(cfg)[0]
            pulls, spreads = flatten_configs(cfg.flatten_options, cfg.sim.layout)
            flattened = flatten_pictured(
                pulls, cell, (spec.width, spec.height), write_image, log, spread=spreads
            ).perceived_entry(pulls.max_actions)
        fold = run_fold if cfg.garment == "towel" else run_garment_fold
        loop = loop_config(cfg, thickness)
        record = fold_and_picture(fold, loop, cell, write_image, log)
        cell.stop_video()
        with cell._lock:
            result = real_cell_result(cfg, record, cell.sim_time, time.perf_counter() - wall0)
            if flattened is not None:
                result["perceived"]["flatten"] = flattened
            result["transport"] = "ros"
            result["arm_interface"] = "actions"
            result["gripper_lead_s"] = gripper_lead
            result["gripper_effort_n"] = cell.drivers[0].gripper_effort  # the goals' max_effort
            result["slip_watch"] = slip_watch(cell, travel_from)
            if cfg.arms > 1:
                result["together_lead_s"] = together_lead
            result["cell"] = "real"
            result["cloth_thickness_m"] = thickness
            result["cloth_thickness_given"] = cloth_thickness is not None
            if cell.gate is not None:
                result["operator"] = cell.gate.record()
            writer.write_result(result)
            path = writer.commit(require_cloth=False)
    result["out_dir"] = str(Path(path))
    return result


def run_dry_task(
    fold_args: str,
    real: bool,
    arm_interface: str = "topics",
    cloth_thickness: float | None = None,
    log=rospy.loginfo,
) -> DryRun:
    """A dry run over ROS (foldbot.dry_run): the cell's first frame perceived, every stage and
    motion planned by the planner node, nothing moved (on a real cell the grippers are not even
    opened); plan.json and overlay_planK.png written to the fold's --out."""
    args, cfg = parse_fold_args(fold_args)
    check_dry_run_config(cfg.garment, cfg.start, injected_faults(cfg), cfg.arms)
    check_dry_run_output(Path(args.out), args.overwrite)
    cell = RosCell(
        cfg.sim.layout,
        None,
        cfg.arms,
        "actions" if real else arm_interface,
        robot_class(cfg.robot).ARM_JOINT_NAMES,
        cell="real" if real else "sim",
    )
    if real:
        cell.wait_for_real_cell(open_grippers=False)
        thickness = real_cell_thickness(cfg, cloth_thickness)
    else:
        cell.wait_ready()
        thickness = float(
            cell.mesh.take(lambda m: True, "cloth mesh from the sim node")["thickness"]
        )
    if cfg.start == "crumpled":  # its first flattening pull (one arm)
        pulls, _spreads = flatten_configs(cfg.flatten_options, cfg.sim.layout)
        size = seeded_garment(cfg)[0]
        run = dry_run_flatten(pulls, cell, (size.width, size.height), cfg.motion.speed_scale, log)
    else:
        run = dry_run(loop_config(cfg, thickness), cell, cfg.motion.speed_scale, log)
    run.record["cell"] = "real" if real else "sim"
    run.record["recipe"] = cfg.recipe
    write_dry_run(run, Path(args.out), args.overwrite)
    return run


def run_task(
    fold_args: str,
    log=rospy.loginfo,
    arm_interface: str = "topics",
    gripper_lead: float | None = GRIPPER_LEAD_S,
    together_lead: float = TOGETHER_LEAD_S,
    finger_joints: str = "",
    finger_travel: float | None = None,
    gripper_effort: float = 0.0,
) -> dict:
    """Fold over topics and write the episode folder; returns result.json's content.
    `finger_travel`: the slip watch's, through the actions (None: finger_travel_for's, from the
    simulated cloth's thickness); `gripper_effort`: the max_effort (N) of the gripper goals
    through the actions (0: no limit)."""
    args, cfg = parse_fold_args(fold_args)
    layout = cfg.sim.layout
    writer = EpisodeWriter(args.out, overwrite=args.overwrite, fps=max(cfg.video_fps, 1.0))
    wall0 = time.perf_counter()
    with writer, contextlib.ExitStack() as stack:
        cell = RosCell(
            layout,
            writer if cfg.video_fps > 0 else None,
            cfg.arms,
            arm_interface,
            robot_class(cfg.robot).ARM_JOINT_NAMES,
            finger_names=finger_joint_names(
                finger_joints, robot_class(cfg.robot).FINGER_JOINT_NAMES
            ),
            gripper_lead=gripper_lead,
            together_lead=together_lead,
            gripper_effort=gripper_effort,
        )
        stack.callback(cell.stop_video)  # before the writer closes the video, error or not
        cell.gate = operator_gate(args)
        cell.wait_ready()
        initial = convert.cloud_array(cell.truth.take(lambda m: True, "initial ground truth"))
        mesh = cell.mesh.take(lambda m: True, "cloth mesh from the sim node")
        thickness = float(mesh["thickness"])  # the loop's layer height where depth tells nothing
        travel, travel_from = finger_travel_for(finger_travel, finger_joints, thickness)
        cell.set_finger_travel(travel)
        faces = np.array(mesh["faces"], dtype=np.int64)

        def write_image(name: str, image: np.ndarray) -> None:
            with cell._lock:  # the video's frames are written from the camera's callbacks
                writer.write_image(name, image)

        flattened = None
        if cfg.start == "crumpled":
            spec = seeded_garment(cfg)[0]
            pulls, spreads = flatten_configs(cfg.flatten_options, cfg.sim.layout)
            flattened, initial = flatten_and_score(
                cell,
                (spec.width, spec.height),
                initial,
                cell.ground_truth,
                faces,
                float(mesh["flat_area"]),
                write_image,
                log,
                cfg=pulls,
                spread=spreads,
            )
        fold = run_fold if cfg.garment == "towel" else run_garment_fold
        record = fold_and_picture(fold, loop_config(cfg, thickness), cell, write_image, log)
        final = cell.ground_truth()
        score = score_episode(initial, final, faces, record.fold_lines, thickness)
        cell.stop_video()
        with cell._lock:
            writer.write_cloth(faces, initial, final, thickness)
            result = episode_result(
                cfg,
                seeded_garment(cfg)[0],
                seeded_pose(cfg, layout.workspace_center_xy),
                score,
                record,
                cell.sim_time,
                time.perf_counter() - wall0,
                cfg.cell_camera,
            )
            if flattened is not None:
                result["flatten"] = flattened
            result["cloth_fastest_slide_mps"] = cell.fastest_slide
            if cell.guard_restored is not None:
                result["crossing_guard_restored"] = int(cell.guard_restored)
            if cfg.fault_grasp_offset > 0 or cfg.fault_slip > 0:  # as in process
                result["faults"] = {
                    "grasp_offset_m": cfg.fault_grasp_offset,
                    "slip_fraction": cfg.fault_slip,
                    "slipped": cell.fault_slipped,
                }
            result["first_frame_keypoint_error_mm"] = first_frame_keypoint_errors(
                cfg, seeded_garment(cfg)[1], initial, record.initial_state
            )
            result["transport"] = "ros"
            result["arm_interface"] = arm_interface
            if arm_interface == "actions":
                result["gripper_lead_s"] = gripper_lead
                result["gripper_effort_n"] = cell.drivers[0].gripper_effort
                result["slip_watch"] = slip_watch(cell, travel_from)
                if cfg.arms > 1:
                    result["together_lead_s"] = together_lead
            result["cell"] = "sim"
            if cell.gate is not None:
                result["operator"] = cell.gate.record()
            writer.write_result(result)
            path = writer.commit()
    result["out_dir"] = str(Path(path))
    return result


def slip_watch(cell: RosCell, travel_from: str) -> dict:
    """result.json's record of the watch for a slip through the drivers: each arm's finger
    joints watched on /joint_states (none: no watch), the travel that counts as lost and where
    it came from (finger_travel_for)."""
    return {
        "finger_joints": [list(d.finger_joints) for d in cell.drivers],
        "finger_travel": cell.drivers[0].slip_travel if cell.drivers else None,
        "finger_travel_from": travel_from,
    }


def outcome_line(result: dict) -> str:
    """One line on a fold's outcome: its scores, or on a real cell (unscored) what the camera
    saw."""
    if result.get("scored", True):
        return (
            f"fold {'succeeded' if result['success'] else 'FAILED'}: fold error "
            f"{result['fold_error_mm']:.1f} mm, normalized performance "
            f"{result['normalized_performance']:.3f}"
        )
    return unscored_outcome(result["perceived"])


def main(argv: list[str] | None = None) -> int:
    rospy.init_node("foldbot_task", argv=argv if argv is not None else sys.argv)
    pub = rospy.Publisher(TOPICS["episode"], String, queue_size=1, latch=True)
    # Every parameter read now: a cell that fails may take the master down with it.
    error_file = rospy.get_param(ERROR_FILE_PARAM, "")
    fold_args = rospy.get_param(FOLD_ARGS_PARAM)
    lead = float(rospy.get_param(GRIPPER_LEAD_PARAM, GRIPPER_LEAD_S))
    lead = None if lead < 0 else lead
    together = float(rospy.get_param(TOGETHER_LEAD_PARAM, TOGETHER_LEAD_S))
    travel = float(rospy.get_param(FINGER_TRAVEL_PARAM, -1.0))
    fingers = {
        "finger_joints": str(rospy.get_param(FINGER_JOINTS_PARAM, "")),
        "finger_travel": None if travel <= 0 else travel,  # finger_travel_for's
        "gripper_effort": float(rospy.get_param(GRIPPER_EFFORT_PARAM, 0.0)),
    }
    try:
        if rospy.get_param(DRY_RUN_PARAM, False):
            thickness = float(rospy.get_param(CLOTH_THICKNESS_PARAM, -1.0))
            run = run_dry_task(
                fold_args,
                rospy.get_param(CELL_PARAM, "sim") == "real",
                rospy.get_param(ARM_INTERFACE_PARAM, "topics"),
                None if thickness < 0 else thickness,
            )
            print(run.summary(), flush=True)
            rospy.signal_shutdown("dry run done")
            return 0
        if rospy.get_param(CELL_PARAM, "sim") == "real":
            thickness = float(rospy.get_param(CLOTH_THICKNESS_PARAM, -1.0))
            result = run_real_task(
                fold_args,
                gripper_lead=lead,
                together_lead=together,
                cloth_thickness=None if thickness < 0 else thickness,
                **fingers,
            )
        else:
            result = run_task(
                fold_args,
                arm_interface=rospy.get_param(ARM_INTERFACE_PARAM, "topics"),
                gripper_lead=lead,
                together_lead=together,
                **fingers,
            )
    except errors.FoldbotError as exc:
        failure = {"ok": False, "error": str(exc), "error_type": type(exc).__name__}
        if getattr(exc, "__notes__", None):  # where the video up to the error was left
            failure["notes"] = list(exc.__notes__)
        if exc.facts:  # what the episode measured before it (e.g. how far flattening got)
            failure["facts"] = to_jsonable(exc.facts)
        with contextlib.suppress(rospy.ROSException):  # no master left to publish through
            pub.publish(String(data=json.dumps(failure)))
        if error_file:
            Path(error_file).write_text(json.dumps(failure))
        rospy.logerr("fold failed: %s", exc)
        print(f"foldbot: error: {exc}", file=sys.stderr, flush=True)
        rospy.signal_shutdown("fold failed")
        return 2
    pub.publish(
        String(
            data=json.dumps(
                {
                    "ok": True,
                    **{
                        k: result[k]
                        for k in (
                            "success",
                            "fold_error_mm",
                            "normalized_performance",
                            "coverage",
                            "out_dir",
                        )
                    },
                }
            )
        )
    )
    print(f"{outcome_line(result)}; episode written to {result['out_dir']}", flush=True)
    rospy.signal_shutdown("fold done")
    return 0
