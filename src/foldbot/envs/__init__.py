"""Gymnasium environments over the simulated cell (the optional `envs` extra: gymnasium).

- `towel_flatten`: TowelFlatten, a crumpled towel flattened by pick-and-place from RGB-D, and
  TowelSpread, the same with two arms whose step is a spread from two grasp points.
- `episode_process`: one episode's simulation in a fresh child process (Bullet's soft-body
  state is process-global, so a seed reproduces only as the first simulation in its process).

`import foldbot.envs` registers the environments with Gymnasium:
`gymnasium.make("foldbot/TowelFlatten-v0")`, `gymnasium.make("foldbot/TowelSpread-v0")`.
"""

from __future__ import annotations

try:
    from gymnasium.envs.registration import register, registry
except ImportError as exc:  # the optional extra is not installed
    raise ImportError(
        "foldbot.envs needs Gymnasium, the optional `envs` extra: pip install -e '.[envs]' "
        "(make install-test includes it)"
    ) from exc

from foldbot.envs.towel_flatten import (
    TowelFlattenConfig,
    TowelFlattenEnv,
    TowelSpreadConfig,
    TowelSpreadEnv,
)

ENV_IDS = ("foldbot/TowelFlatten-v0", "foldbot/TowelSpread-v0")
"""The environments this package registers."""

for _id, _cls in zip(ENV_IDS, ("TowelFlattenEnv", "TowelSpreadEnv"), strict=True):
    if _id not in registry:
        register(id=_id, entry_point=f"foldbot.envs.towel_flatten:{_cls}")

__all__ = [
    "ENV_IDS",
    "TowelFlattenConfig",
    "TowelFlattenEnv",
    "TowelSpreadConfig",
    "TowelSpreadEnv",
]
