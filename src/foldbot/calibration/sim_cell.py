"""The simulated cell as a calibration sees it: the arm with a board on its tool, the camera
wherever it was put. The run reads only the camera's intrinsics, its images and the joints; the
camera's true pose is kept for the comparison alone (`true_T_world_camera`)."""

from __future__ import annotations

import numpy as np

from foldbot.calibration.board import CalibrationBoard
from foldbot.calibration.capture import VIEW_WORDS, CalibrationCell, pose_matrix
from foldbot.calibration.views import BoardMount, CalibrationView
from foldbot.control.executor import ArmExecutor, move_joints_together
from foldbot.sim.calibration_board import attach_board, board_twin
from foldbot.sim.camera import CameraConfig, RGBDCamera
from foldbot.sim.layout import CellLayout
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimConfig, SimWorld

SETTLE_S = 0.5
"""Rest after each move before the frame is taken (s): the board's bracket stops swinging."""


class SimCalibrationCell(CalibrationCell):
    """A cell with no cloth: the arm (or two, `arms`), a board on the tool of arm `arm` and the
    camera `camera` describes. Another arm stands at its home, where it may hide a view."""

    def __init__(
        self,
        robot: str,
        camera: CameraConfig,
        board: CalibrationBoard,
        mount: BoardMount,
        sim: SimConfig,
        arms: int = 1,
        arm: int = 0,
        speed_scale: float = 1.0,
    ) -> None:
        layouts = sim.layout.arm_layouts(arms)
        self.world = SimWorld(sim)
        self.model_world = SimWorld(SimConfig(time_step=sim.time_step, layout=sim.layout))
        try:
            self._build(robot, camera, board, mount, layouts, arm, speed_scale)
        except BaseException:  # e.g. a board too large to print: no PyBullet client left open
            self.close()
            raise

    def _build(
        self,
        robot: str,
        camera: CameraConfig,
        board: CalibrationBoard,
        mount: BoardMount,
        layouts: tuple[CellLayout, ...],
        arm: int,
        speed_scale: float,
    ) -> None:
        robots = [make_robot(robot, self.world.client, lay) for lay in layouts]
        self.robot = robots[arm]
        self.arm_index = arm
        self.model = make_robot(robot, self.model_world.client, layouts[arm])
        self.executor = ArmExecutor(
            self.world,
            self.robot,
            None,  # type: ignore[arg-type]  # no cloth to grasp: joint moves only
            model=self.model,
            model_table_id=self.model_world.table_id,
            speed_scale=speed_scale,
            model_obstacle_ids=self.model_world.obstacle_ids,
        )
        self.board_id = attach_board(self.robot, board, mount)
        # The board's plate on the twin's tool: kept clear of the layout's obstacles too.
        self.executor.carry_body(
            "the board", board_twin(self.model_world.client, board), mount.T_tcp_board()
        )
        self.camera = RGBDCamera(self.world.client, camera)
        self.world.step(int(SETTLE_S / self.world.time_step))

    @property
    def true_T_world_camera(self) -> np.ndarray:
        """Ground truth, for measuring the calibration only."""
        return self.camera.T_world_camera

    def intrinsics(self) -> tuple[np.ndarray, np.ndarray, int, int]:
        intr = self.camera.intrinsics
        return intr.K, np.zeros(5), intr.width, intr.height

    @property
    def planner(self) -> ArmExecutor:  # type: ignore[override]
        return self.executor

    def rest_positions(self) -> tuple[np.ndarray, np.ndarray]:
        return self.robot.joint_positions(), np.asarray(self.robot.home_q, dtype=float)

    def move_to(self, view: CalibrationView) -> None:
        q0 = self.robot.joint_positions()
        q = self.model.solve_ik(view.position, view.quaternion, q_seed=q0)
        self.executor.check_joint_move(q0, q)
        traj = self.executor.joint_move_trajectory(q0, q)
        self.confirm_move(view.name, VIEW_WORDS, traj.duration)
        move_joints_together([(self.executor, q)], view.name, [traj])
        self.world.step(int(SETTLE_S / self.world.time_step))

    def frame(self) -> tuple[np.ndarray, np.ndarray]:
        obs = self.camera.observe()
        q = self.robot.joint_positions()
        return obs.rgb, pose_matrix(*self.model.fk_tcp(q))

    def finish(self) -> None:
        q0, home = self.robot.joint_positions(), self.robot.home_q
        traj = self.executor.joint_move_trajectory(q0, home)
        self.confirm_move("home", "joint move back to its home, the board away", traj.duration)
        move_joints_together([(self.executor, home)], "home", [traj])

    def close(self) -> None:
        self.world.close()
        self.model_world.close()
