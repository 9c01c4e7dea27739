import numpy as np
import pytest

from foldbot.sim.rest import STILL_CHECKS, RestWatch


def watch_of(world, robot, cloth) -> RestWatch:
    return RestWatch(cloth.sim_vertices, [robot.joint_velocities], world.time_step)


def steps_to_rest(world, watch: RestWatch, limit_s: float = 3.0) -> int:
    """Physics steps until `watch` finds the cell still (fails past `limit_s`)."""
    for k in range(1, round(limit_s / world.time_step) + 1):
        world.step()
        if watch.stepped():
            return k
    raise AssertionError(f"not at rest within {limit_s} s")


def test_a_settled_towel_and_a_still_arm_come_to_rest_after_the_still_checks(cell):
    world, robot, cloth = cell
    watch = watch_of(world, robot, cloth)
    k = steps_to_rest(world, watch)
    # The first check only takes the vertices; STILL_CHECKS more must each find them still.
    assert k == (STILL_CHECKS + 1) * watch.every
    assert watch.rests == 1
    watch.wake()  # a goal arrived: counted again from here
    assert not watch.resting and steps_to_rest(world, watch) == k and watch.rests == 2


def test_a_falling_towel_is_not_at_rest(cell):
    world, robot, cloth = cell
    watch = watch_of(world, robot, cloth)
    cloth.set_node_positions(cloth.node_positions() + [0.0, 0.0, 0.15])  # falls about 0.17 s
    rested = []
    for _ in range(round(0.3 / world.time_step)):
        world.step()
        rested.append(watch.stepped())
    assert not any(rested)


def test_an_idle_world_keeps_its_clock_and_clock_hooks_but_moves_nothing(cell):
    world, robot, cloth = cell
    world.step(round(0.5 / world.time_step))  # a towel falling would move; a settled one creeps
    seen, watched = [], []
    world.add_step_hook(lambda w: seen.append(w.sim_time), on_idle=True)
    world.add_step_hook(lambda w: watched.append(w.sim_time))  # a physics watcher: not idle
    before, q, t0, steps = (
        cloth.sim_vertices(),
        robot.joint_positions(),
        world.sim_time,
        world.steps,
    )
    world.idle(100)
    assert np.array_equal(cloth.sim_vertices(), before)
    assert np.array_equal(robot.joint_positions(), q)
    assert world.steps == steps + 100
    assert world.sim_time == pytest.approx(t0 + 100 * world.time_step)
    assert seen == pytest.approx([t0 + k * world.time_step for k in range(1, 101)])
    assert watched == []
    world.step()
    assert len(seen) == 101 and len(watched) == 1
