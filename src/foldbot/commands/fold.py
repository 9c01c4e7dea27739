"""`foldbot fold`: run one fold episode on the simulated cell and write its episode folder."""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
from pathlib import Path
from typing import TYPE_CHECKING

from foldbot.cloth_options import apply_cloth_options, cloth_options_from_args, cloth_options_help
from foldbot.errors import ConfigError
from foldbot.flatten_options import flatten_options_from_args, flatten_options_help
from foldbot.garments.towel import TowelSpec
from foldbot.io.staging import output_path
from foldbot.loop_options import loop_options_from_args, loop_options_help
from foldbot.operator import OperatorGate
from foldbot.pipeline import (
    ARM_COUNTS,
    FAULT_FIELDS,
    GARMENT_YAW,
    GARMENTS,
    PARK_POSES,
    PERCEPTION_MODES,
    START_STATES,
    EpisodeConfig,
    run_episode,
)
from foldbot.planning.garment_recipes import GARMENT_RECIPE_HELP, GARMENT_RECIPES
from foldbot.planning.motion import MIN_SPEED_SCALE
from foldbot.planning.recipes import RECIPE_HELP, RECIPES
from foldbot.sim.camera import CameraConfig
from foldbot.sim.grasp import JAW_CATCHES
from foldbot.sim.layout import DEFAULT_LAYOUT, LAYOUT_FIELDS, CellLayout, load_layout
from foldbot.sim.robots import ROBOT_NAMES
from foldbot.sim.world import SimConfig

if TYPE_CHECKING:
    from foldbot.bench.suite import EpisodeSpec

DEFAULT_RECIPES = {"towel": "half", **{g: rs[0] for g, rs in GARMENT_RECIPES.items()}}
"""The recipe `--recipe` defaults to, per garment."""
ALL_RECIPES = RECIPES + tuple(r for rs in GARMENT_RECIPES.values() for r in rs)


def add_recipe_and_perception(parser: argparse.ArgumentParser) -> None:
    """`--recipe` and `--perception`, shared by the commands that run episodes."""
    parser.add_argument(
        "--recipe",
        default=None,
        choices=ALL_RECIPES,
        help="fold recipe (default: half for a towel, retail for a tshirt, leg_over_leg for "
        "pants): "
        + "; ".join(f"{k}: {v}" for k, v in {**RECIPE_HELP, **GARMENT_RECIPE_HELP}.items()),
    )
    parser.add_argument(
        "--perception",
        default="vision",
        choices=PERCEPTION_MODES,
        help="keypoints from the RGB-D image (vision) or from simulator ground truth (oracle, "
        "for comparison; from a crumpled start the oracle also plans the flattening pulls, "
        "pulling the true corners onto the laid-flat towel)",
    )


def add_loop_option(parser: argparse.ArgumentParser, where: str) -> None:
    """`--loop-option NAME=VALUE` (repeatable), shared by the commands that run episodes; `where`
    says what it goes over."""
    parser.add_argument(
        "--loop-option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"set one of the closed loop's switches (repeatable; {where}); VALUE is true/false, "
        "an integer, metres, or none: " + loop_options_help(),
    )


def add_cloth_option(parser: argparse.ArgumentParser, where: str) -> None:
    """`--cloth NAME=VALUE` (repeatable), shared by the commands that run episodes; `where` says
    what it goes over."""
    parser.add_argument(
        "--cloth",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"set one of the cloth's physical parameters (repeatable; {where}): "
        + cloth_options_help(),
    )


def add_flatten_option(parser: argparse.ArgumentParser, where: str) -> None:
    """`--flatten-option NAME=VALUE` (repeatable), shared by the commands that run episodes;
    `where` says what it goes over."""
    parser.add_argument(
        "--flatten-option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"set how a crumpled towel is flattened (repeatable; {where}); VALUE is true/false, "
        "an integer, a number in SI units, none, or all/top: " + flatten_options_help(),
    )


def add_arguments(
    parser: argparse.ArgumentParser,
    output: bool = True,
    camera_pose: bool = True,
    faults: bool = True,
) -> None:
    """Options of `foldbot fold`: an episode's, and `--suite` (`output` False: without the
    episode folder's --out and --overwrite, or --gui; `camera_pose` False: without
    --camera-pose, which `ros-fold` defines its own way; `faults` False: without the injected
    faults, which only a simulated cell the fold starts makes: in process, or over ROS)."""
    add_episode_arguments(parser, output)
    if faults:
        add_fault_options(parser)
    if camera_pose:
        add_camera_pose_option(
            parser,
            "perceive from the camera pose a calibration found, as a real cell does: "
            "`foldbot calibrate`'s calibration.json places the simulated camera where it truly "
            "stood and its Observations carry the pose the calibration found, so the "
            "calibration's error reaches the fold; a real cell's (`ros-calibrate`, no truth) "
            "places the camera at its pose, taken as exact. Its image size and intrinsics too, "
            "where the file keeps them (default: perception is given the camera's true pose)",
        )
    parser.add_argument(
        "--suite",
        default=None,
        metavar="NAME",
        help="run the episode a benchmark suite runs for --seed (suites/NAME.toml, or a .toml "
        "path): its towel size and pose draws, start, arms, cloth and loop, exactly as `foldbot "
        "bench` runs it (a seed outside the suite's own as `bench --seeds` runs it), but with a "
        "video (--video-fps) and optionally --gui. --recipe and "
        "--perception pick among the suite's where it has several, --replicate its replicate; "
        "--loop-option, --cloth and --flatten-option are set over the suite's own (a trial, as "
        "`bench --suite` runs one); other episode options are refused beside it",
    )
    parser.add_argument(
        "--episode",
        default=None,
        metavar="ID",
        help="with --suite: the episode by its id (as summary.md and the run's episodes/ folder "
        "name it, e.g. towel-half-vision-open-s0000) instead of --seed, --recipe, --perception "
        "and --replicate",
    )


def add_camera_pose_option(parser: argparse.ArgumentParser, help_text: str) -> None:
    """--camera-pose CALIBRATION.json (args.camera_calibration; calibrated_camera reads it)."""
    parser.add_argument(
        "--camera-pose",
        dest="camera_calibration",
        type=Path,
        default=None,
        metavar="CALIBRATION.json",
        help=help_text,
    )


SUITE_PICKS = ("suite", "episode", "seed", "replicate", "recipe", "perception")
"""With --suite, the options that pick one of its episodes."""
SUITE_FREE = ("video_fps", "out", "overwrite", "gui", "dry_run", "confirm")
"""With --suite, the options that do not change the episode's physics or plan."""
SUITE_CAMERA = ("camera_calibration",)
"""With --suite, the camera a calibration found (--camera-pose) in place of the exact one."""
SUITE_FAULTS = FAULT_FIELDS
"""With --suite, the faults injected into its episode (a trial of the loop's recovery)."""
SUITE_OVER = ("loop_option", "cloth", "flatten_option")
"""With --suite, the options set over the suite's own tables, as `foldbot bench --suite` sets
them: a trial of one of its episodes."""


def add_fault_options(parser: argparse.ArgumentParser) -> None:
    """Faults the simulated cell injects, to watch the closed loop recover
    (EpisodeConfig.fault_grasp_offset and fault_slip; result.json's `faults`)."""
    add_slip_option(parser)
    parser.add_argument(
        "--fault-grasp-offset",
        type=float,
        default=0.0,
        metavar="M",
        help="the episode's first grasp is aimed this far (m, at most 0.2) outward from the "
        "perceived corner, onto bare table (default 0: none): the jaws close on nothing and "
        "the loop re-observes and retries",
    )


def add_slip_option(parser: argparse.ArgumentParser) -> None:
    """--fault-slip: the one fault the cell itself makes (`ros-cell` too; a grasp aimed off the
    cloth is the fold's own)."""
    parser.add_argument(
        "--fault-slip",
        type=float,
        default=0.0,
        metavar="FRACTION",
        help="the episode's first carry loses its cloth this fraction of the way along it, as a "
        "grasp that slips (0 < FRACTION < 1, e.g. 0.3; default 0: none): the gripper reports "
        "the lost hold, the arm lets go, and the loop lays the corner back and plans the stage "
        "again (--loop-option slip_lay_back=false: re-observes and grasps again). Late in "
        "the carry the cloth falls from its highest and can sink through the table, which is "
        "reported as a divergence. Over ROS (`ros-fold`), the sim node's cell slips (through "
        "the drivers' actions the task node sees it on /joint_states, the fingers closing on; "
        "`ros-cell --fault-slip` makes a running cell slip so)",
    )


def add_episode_arguments(parser: argparse.ArgumentParser, output: bool = True) -> None:
    """The options that define one fold episode (`foldbot fold` and `foldbot ros-fold` add
    `--suite` and `--episode`); `output` False leaves out --out, --overwrite and --gui."""
    parser.add_argument(
        "--garment",
        default="towel",
        choices=GARMENTS,
        help="garment to fold; a tshirt's or pants' size is drawn by --seed (default towel)",
    )
    add_recipe_and_perception(parser)
    parser.add_argument("--robot", default="ur5", choices=ROBOT_NAMES, help="arm to use")
    parser.add_argument(
        "--start",
        default="flat",
        choices=START_STATES,
        help="flat (default), or crumpled: the seed crumples the towel and the robot flattens it "
        "(perceived coverage ≥ 0.9, at most 6 actions: pulls with one arm, spreads with two) "
        "before folding",
    )
    parser.add_argument(
        "--park",
        default="home",
        choices=PARK_POSES,
        help="where the arm waits while the camera looks: home (default, over the workspace) "
        "or out_of_view (near the robot base, outside the image)",
    )
    parser.add_argument(
        "--arms",
        type=int,
        default=1,
        choices=ARM_COUNTS,
        help="arms in the cell: 1 (default), or 2 side by side, which carry a stage's two grasps "
        "together and flatten a crumpled towel by lifting, spreading and laying it",
    )
    parser.add_argument("--seed", type=int, default=0, help="randomisation seed (default 0)")
    parser.add_argument(
        "--replicate",
        type=int,
        default=0,
        metavar="K",
        help="0 (default): the cloth where the seed puts it; K > 0: the same cloth laid 0.1 mm "
        "from there, as a suite's replicate K (its episode id ends in -rK)",
    )
    parser.add_argument(
        "--width",
        type=float,
        default=None,
        help="towel width in m (0.05–1.0, default 0.30; the camera sees a whole towel up to "
        "about 0.6 m, a larger one is refused before the arm moves)",
    )
    parser.add_argument(
        "--height",
        type=float,
        default=None,
        help="towel height in m (0.05–1.0, default 0.30; as --width)",
    )
    parser.add_argument(
        "--resolution",
        type=int,
        default=None,
        help="cloth vertices along the towel's longer side (4–40, default 16)",
    )
    parser.add_argument(
        "--max-vertices",
        type=int,
        default=None,
        metavar="N",
        help="at most N cloth vertices on the towel: where --resolution along the longer side "
        "gives more (a near-square towel), fewer along it; a physics step's cost grows with the "
        "vertices (default: no bound)",
    )
    parser.add_argument(
        "--odd-grid",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="odd vertex counts along both sides, so the half folds' lines are vertex rows: a "
        "mass-spring mesh creases only at vertices (default; --resolution 16 becomes 17). "
        "--no-odd-grid keeps the proportional counts",
    )
    parser.add_argument(
        "--garment-edge-length",
        type=float,
        default=None,
        metavar="M",
        help="a tshirt's or pants' mesh edge length in m (0.005–0.1; default 0.025): coarser "
        "meshes simulate faster",
    )
    parser.add_argument(
        "--garment-yaw",
        type=float,
        default=math.degrees(GARMENT_YAW),
        metavar="DEG",
        help="a tshirt's or pants' base yaw in degrees, the seed's ±15° added (default 90: its "
        "top toward the robot; 180 or 0: sideways, its top toward -y or +y)",
    )
    parser.add_argument("--mass", type=float, default=None, help="cloth mass in kg (default 0.1)")
    parser.add_argument(
        "--time-step",
        type=float,
        default=SimConfig.time_step,
        metavar="S",
        help=f"physics step in s (default 1/360 = {SimConfig.time_step:.6f}; a suite's "
        "[episode] time_step; smaller steps cost time and blow crumpled heaps up less often)",
    )
    parser.add_argument(
        "--speed-scale",
        type=float,
        default=1.0,
        metavar="S",
        help=f"fraction of full speed the arm moves at ({MIN_SPEED_SCALE:g}–1, default 1; a "
        "suite's [episode] speed_scale): the same paths, 1/S times as long, as a real arm's "
        "speed slider for a first run",
    )
    parser.add_argument(
        "--layout",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="the cell's layout (world frame, m): a TOML file setting any of "
        + ", ".join(LAYOUT_FIELDS)
        + " (e.g. table_height = 0.72, robot_base_xyz = [0, 0, 0.72], workspace_center_xy = "
        "[0.5, 0.05]); the rest at the default cell's (a 1.2 m table, its top at 0.75 m, the arm "
        "on it at the origin, a 0.6 m workspace centred at (0.45, 0), no obstacles). Each "
        "[[obstacles]] table (name, center_xyz, size_xyz, yaw_deg: a box) is a fixture the arm keeps "
        "2 cm from. The simulated cell is built so, its camera moved with the workspace; a real "
        "cell (ros-fold --cell real) is planned for it",
    )
    parser.add_argument(
        "--jaw-catch",
        choices=JAW_CATCHES,
        default="vertices",
        help="what the closed jaws hold: the cloth's mesh points between the pads (default), or "
        "also cloth that passes between the pads between mesh points (surface; a suite's "
        "[episode] jaw_catch)",
    )
    add_loop_option(parser, "a suite's [loop_options]")
    add_cloth_option(parser, "a suite's [cloth]; --mass is mass=")
    add_flatten_option(parser, "a suite's [flatten_options]; with --start crumpled")
    parser.add_argument(
        "--video-fps", type=float, default=10.0, help="video frames per simulated second (0 = off)"
    )
    if not output:
        parser.set_defaults(out=None, overwrite=False, gui=False)
        return
    parser.add_argument("--out", type=output_path, required=True, help="episode output folder")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace DIR if it holds an earlier episode"
    )
    parser.add_argument("--gui", action="store_true", help="open the PyBullet GUI")
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help="move nothing: look once, plan every stage (a later stage on the outline the one "
        "before predicts) carried as the fold carries it (two arms' corners together, a stack "
        "by its edge's middle) and every pick-and-place's motion from where the arms stand, "
        "and write DIR/plan.json (each action feasible or why not, its steps' seconds at "
        "--speed-scale) and overlay_planK.png; a towel or garment lying flat",
    )
    parser.add_argument(
        "--confirm",
        action="store_true",
        help="before each motion (a pick-and-place: arm, grasp, place, seconds; a park; the "
        "lift after a missed grasp) say what it will do and wait for the operator: Enter "
        "moves, s stops the fold there (the episode is then left as DIR.failed); for a first "
        "run on a real arm",
    )


def config_from_args(args: argparse.Namespace) -> EpisodeConfig:
    """Build the episode config (validated) from parsed options."""
    if getattr(args, "suite", None) is not None:
        return suite_episode_config(args)
    if getattr(args, "episode", None) is not None:
        raise ConfigError(f"--episode {args.episode} names a suite's episode: give --suite too")
    base = EpisodeConfig()
    cloth_options = cloth_options_from_args(args.cloth)
    if args.mass is not None:
        if "mass" in cloth_options:
            raise ConfigError("the cloth's mass is given twice (--mass and --cloth mass=)")
        cloth_options["mass"] = args.mass
    cloth = apply_cloth_options(base.cloth, cloth_options)
    layout = DEFAULT_LAYOUT if args.layout is None else load_layout(args.layout)
    return EpisodeConfig(
        garment=args.garment,
        recipe=args.recipe or DEFAULT_RECIPES[args.garment],
        robot=args.robot,
        perception=args.perception,
        seed=args.seed,
        replicate=args.replicate,
        start=args.start,
        park=args.park,
        arms=args.arms,
        jaw_catch=args.jaw_catch,
        towel=towel_from_args(args),
        garment_edge_length=args.garment_edge_length,
        garment_yaw=math.radians(args.garment_yaw),
        cloth=cloth,
        sim=SimConfig(
            time_step=args.time_step,
            gui=args.gui,
            layout=layout,
        ),
        camera=calibrated_camera(args, base.camera, layout),
        motion=dataclasses.replace(base.motion, speed_scale=args.speed_scale),
        video_fps=args.video_fps,
        loop_options=loop_options_from_args(args.loop_option),
        flatten_options=flatten_options_from_args(args.flatten_option),
        **faults_from_args(args),
    )


def given_flag(name: str, value: object) -> str:
    """The flag an option `name` was given as: --name, or --no-name for a switch turned off."""
    return ("--no-" if value is False else "--") + name.replace("_", "-")


TOWEL_OPTIONS = ("width", "height", "resolution", "odd_grid", "max_vertices")
"""The options that shape a towel's mesh (None where not given); a T-shirt's or pants' size is
the seed's draw and its mesh --garment-edge-length's."""
TOWEL_DEFAULTS = TowelSpec(odd_grid=True)
"""The towel the command folds where its options are not given (odd grid: see --odd-grid)."""


def towel_from_args(args: argparse.Namespace) -> TowelSpec:
    """The towel the options shape; ConfigError where a towel option is given for a T-shirt or
    pants, or --garment-edge-length for a towel (each would be silently unused)."""
    given = [name for name in TOWEL_OPTIONS if getattr(args, name) is not None]
    if args.garment != "towel" and given:
        flags = [given_flag(name, getattr(args, name)) for name in given]
        whose = {"tshirt": "a T-shirt's", "pants": "the pants'"}[args.garment]
        raise ConfigError(
            f"{', '.join(flags)} {'shapes' if len(flags) == 1 else 'shape'} a towel; {whose} "
            "size is the seed's draw and its mesh --garment-edge-length's: drop "
            + ("it" if len(flags) == 1 else "them")
        )
    if args.garment == "towel" and args.garment_edge_length is not None:
        raise ConfigError(
            "--garment-edge-length sets a tshirt's or pants' mesh; a towel's is --resolution's "
            "(and --max-vertices'): drop it"
        )
    return dataclasses.replace(TOWEL_DEFAULTS, **{name: getattr(args, name) for name in given})


def faults_from_args(args: argparse.Namespace) -> dict[str, float]:
    """The EpisodeConfig fault fields --fault-slip and --fault-grasp-offset set (none where the
    command has no such options)."""
    return {name: getattr(args, name) for name in SUITE_FAULTS if hasattr(args, name)}


def calibrated_camera(
    args: argparse.Namespace, camera: CameraConfig, layout: CellLayout
) -> CameraConfig:
    """`camera` as the calibration --camera-pose names places it (CameraPlacement.sim_camera),
    or unchanged without one."""
    path = getattr(args, "camera_calibration", None)
    if path is None:
        return camera
    from foldbot.commands.check_layout import camera_placement

    return camera_placement(path, layout).sim_camera(camera)


def perceived_pose_line(camera: CameraConfig) -> str:
    """What the fold's perception was told of the camera's pose, where a calibration gave it."""
    if camera.reported_pose is None:
        return ""
    from foldbot.calibration.hand_eye import pose_error_record

    off = pose_error_record(camera.reported_T_world_camera, camera.T_world_camera)
    return (
        f"camera: perceived from {camera.reported_pose_source}'s pose, "
        f"{off['calibration_error_mm']:.2f} mm and {off['calibration_error_deg']:.3f}° from where "
        "it truly stands"
    )


def check_confirm(args: argparse.Namespace) -> None:
    """ConfigError for --confirm where nothing moves: a dry run."""
    if getattr(args, "confirm", False) and getattr(args, "dry_run", False):
        raise ConfigError("--confirm asks before each motion, and --dry-run makes none: drop one")


def run(args: argparse.Namespace) -> int:
    """Run the episode and print where its outputs are."""
    cfg = config_from_args(args)
    if words := perceived_pose_line(cfg.camera):
        print(words)
    check_confirm(args)
    if args.dry_run:
        from foldbot.pipeline import dry_run_episode

        run = dry_run_episode(cfg, args.out, overwrite=args.overwrite)
        print(run.summary())
        print(f"plan written to {args.out}")
        return 0 if run.record["feasible"] else 1
    gate = OperatorGate() if args.confirm else None
    result = run_episode(cfg, args.out, overwrite=args.overwrite, gate=gate)
    flat = result.get("flatten")
    if flat is not None:
        print(
            f"flattening {'succeeded' if flat['success'] else 'FAILED'}: coverage "
            f"{flat['coverage_start']:.2f} → {flat['coverage_end']:.2f} in {flat['actions']} actions"
        )
    perfect = result.get("perfect_fold_error_mm") or 0.0
    print(
        f"fold {'succeeded' if result['success'] else 'FAILED'}: "
        f"fold error {result['fold_error_mm']:.1f} mm"
        + (f" (a physically perfect fold scores {perfect:.1f})" if perfect >= 0.05 else "")
        + ", "
        f"normalized performance {result['normalized_performance']:.3f}, "
        f"coverage {result['coverage']:.2f}, "
        f"{result['sim_seconds']:.1f} s simulated in {result['wall_seconds']:.1f} s"
    )
    if result.get("self_crossings"):
        print(
            f"  the simulated cloth passed through itself in the fold ({result['self_crossings']} "
            "mesh edges cross it), which no real cloth does; scored all the same"
        )
    print(f"episode written to {result['out_dir']}")
    return 0


def suite_episode_config(args: argparse.Namespace) -> EpisodeConfig:
    """The EpisodeConfig `foldbot bench --suite args.suite` runs for the episode the options
    pick (pick_suite_episode), with this command's video rate and GUI (neither changes its
    physics) and the camera pose a calibration found (--camera-pose), where given."""
    cfg = pick_suite_episode(args).to_config()
    return dataclasses.replace(
        cfg,
        **faults_from_args(args),
        video_fps=args.video_fps,
        sim=dataclasses.replace(cfg.sim, gui=args.gui),
        camera=calibrated_camera(args, cfg.camera, cfg.sim.layout),
    )


def pick_suite_episode(args: argparse.Namespace) -> EpisodeSpec:
    """The episode of suite `args.suite` that --episode, or --seed (and replicate, recipe,
    perception), picks, with the loop, cloth and flatten options given set over its own;
    ConfigError where another episode option is given beside --suite, or where the suite has
    no such episode or several."""
    defaults = argparse.ArgumentParser(add_help=False)
    add_arguments(defaults)
    given = [
        given_flag(name, getattr(args, name, default))
        for name, default in vars(defaults.parse_args(["--out", "-"])).items()
        if name not in SUITE_PICKS + SUITE_FREE + SUITE_OVER + SUITE_CAMERA + SUITE_FAULTS
        and getattr(args, name, default) != default
    ]
    if given:
        raise ConfigError(
            f"--suite {args.suite} sets the episode; drop {', '.join(given)} (beside --suite only "
            "--seed, --replicate, --recipe, --perception, --video-fps, --out, --overwrite, "
            "--gui, --dry-run, --confirm, --camera-pose, --fault-slip, --fault-grasp-offset, "
            "and --loop-option, --cloth and --flatten-option over the suite's own, are allowed)"
        )
    return _picked(args, defaults).with_options(
        loop_options_from_args(args.loop_option),
        cloth_options_from_args(args.cloth),
        flatten_options_from_args(args.flatten_option),
    )


def _picked(args: argparse.Namespace, defaults: argparse.ArgumentParser) -> EpisodeSpec:
    """The suite's episode --episode, or --seed (and replicate, recipe, perception), picks."""
    from foldbot.bench.suite import load_suite

    if args.episode is not None:
        picks = [
            "--" + name
            for name in ("seed", "replicate", "recipe", "perception")
            if getattr(args, name) != defaults.get_default(name)
        ]
        if picks:
            raise ConfigError(f"--episode names the episode; drop {', '.join(picks)}")
        # An id's seed may lie outside the suite's own (a run with `bench --seeds`).
        seed = re.search(r"-s(\d+)(?:-r\d+)?$", args.episode)
        suite = own = load_suite(args.suite)
        if seed and int(seed[1]) not in own.axes["seeds"]:
            suite = load_suite(args.suite, [int(seed[1])])
        picked = [e for e in suite.episodes if e.id == args.episode]
        if not picked:
            ids = [e.id for e in own.episodes]
            shown = ", ".join(ids[:4]) + (f", … ({len(ids)} in all)" if len(ids) > 4 else "")
            raise ConfigError(
                f"suite {suite.name!r} has no episode {args.episode!r}; its ids: {shown}"
            )
        return picked[0]
    if args.seed < 0:
        raise ConfigError(f"--seed must be an integer ≥ 0, got {args.seed}")
    suite = load_suite(args.suite, [args.seed])  # any seed, drawn as the suite draws it
    picked = [
        e
        for e in suite.episodes
        if e.seed == args.seed
        and e.replicate == args.replicate
        and (args.recipe is None or e.recipe == args.recipe)
        and e.perception == args.perception
    ]
    if not picked:
        have = sorted({(e.recipe, e.perception) for e in suite.episodes})
        reps = suite.axes["replicates"]
        raise ConfigError(
            f"suite {suite.name!r} has no episode with replicate {args.replicate}, recipe "
            f"{args.recipe or 'any'} and perception {args.perception}; its replicates: "
            f"0–{reps - 1}, its recipe and perception pairs: "
            + ", ".join(f"{r}/{p}" for r, p in have)
        )
    if len(picked) > 1:
        raise ConfigError(
            f"suite {suite.name!r} runs {len(picked)} episodes for seed {args.seed}: "
            + ", ".join(e.id for e in picked)
            + "; pick one with --recipe, or by its id with --episode"
        )
    return picked[0]
