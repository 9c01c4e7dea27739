"""Does PyBullet change a soft body's friction or collision margin after it is loaded?

A probe for per-phase cloth settings (less friction while flattening, a thicker cloth while a
stack is folded): a settled 20 cm towel is given 0.5 m/s along x and slides for 1 s, once as
built, once after `changeDynamics(lateralFriction=0.05)`, and once built with friction 0.05;
and a resting towel's height is read before and after `changeDynamics(collisionMargin=0.02)`.
Prints the slides (mm) and heights (mm above the table).

    .venv/bin/python scripts/probe_soft_body_changes.py
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import pybullet as p

from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.world import SimWorld


def settled_towel(friction: float = 1.0) -> tuple[SimWorld, SoftCloth]:
    """A fresh world with a 20 cm towel (8 × 8 vertices) settled on the table."""
    world = SimWorld()
    mesh = make_towel(TowelSpec(0.2, 0.2, 8))
    cloth = SoftCloth(
        world.client, mesh, ClothConfig(friction=friction), world.layout.table_height, (0.45, 0.0)
    )
    settle(world, cloth, 2.0)
    return world, cloth


def slide_mm(friction: float = 1.0, changed_to: float | None = None) -> float:
    """How far (mm) the towel's centroid slides in 1 s from 0.5 m/s along x."""
    world, cloth = settled_towel(friction)
    if changed_to is not None:
        p.changeDynamics(
            cloth.body_id, -1, lateralFriction=changed_to, physicsClientId=world.client
        )
    x0 = cloth.sim_vertices()[:, 0].mean()
    p.resetBaseVelocity(cloth.body_id, linearVelocity=[0.5, 0, 0], physicsClientId=world.client)
    world.step(round(1.0 / world.time_step))
    slid = 1000 * (cloth.sim_vertices()[:, 0].mean() - x0)
    p.disconnect(world.client)
    return float(slid)


def margin_heights_mm() -> tuple[float, float, float]:
    """The margin (mm) and a resting towel's mean height (mm) before and after its collision
    margin is set to 20 mm and it rests 2 s more."""
    world, cloth = settled_towel()

    def height() -> float:
        return 1000 * float((cloth.sim_vertices()[:, 2] - world.layout.table_height).mean())

    before = height()
    p.changeDynamics(cloth.body_id, -1, collisionMargin=0.02, physicsClientId=world.client)
    world.step(round(2.0 / world.time_step))
    after = height()
    margin = 1000 * cloth.margin
    p.disconnect(world.client)
    return margin, before, after


def main() -> None:
    print(f"slide, friction as built (1.0):                {slide_mm():.1f} mm")
    print(f"slide, then changeDynamics(lateralFriction=0.05): {slide_mm(changed_to=0.05):.1f} mm")
    print(f"slide, built with friction 0.05:               {slide_mm(0.05):.1f} mm")
    margin, before, after = margin_heights_mm()
    print(
        f"resting height with its {margin:.1f} mm margin {before:.2f} mm; "
        f"after changeDynamics(collisionMargin=0.02) {after:.2f} mm"
    )


if __name__ == "__main__":
    main()
