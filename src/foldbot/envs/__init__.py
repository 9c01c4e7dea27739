"""Gymnasium environments over the simulated cell (the optional `envs` extra: gymnasium).

- `towel_flatten`: TowelFlatten, a crumpled towel flattened by pick-and-place from RGB-D, and
  TowelSpread, the same with two arms whose step is a spread from two grasp points.
- `towel_fold`: TowelFold, a flat towel folded to a recipe's goal by one-arm carries, and
  TowelFoldPair, the same with two arms whose step is two carries at once.
- `towel_task`: what they share (episodes per seed, observations, actions, the ends).
- `episode_process`: one episode's simulation in a fresh child process (Bullet's soft-body
  state is process-global, so a seed reproduces only as the first simulation in its process).

`import foldbot.envs` registers the environments with Gymnasium:
`gymnasium.make("foldbot/TowelFlatten-v0")`, `gymnasium.make("foldbot/TowelSpread-v0")`,
`gymnasium.make("foldbot/TowelFold-v0", recipe="quarter")`,
`gymnasium.make("foldbot/TowelFoldPair-v0", recipe="quarter")`.
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
from foldbot.envs.towel_fold import (
    TowelFoldConfig,
    TowelFoldEnv,
    TowelFoldPairConfig,
    TowelFoldPairEnv,
)

_ENTRY_POINTS = {
    "foldbot/TowelFlatten-v0": "foldbot.envs.towel_flatten:TowelFlattenEnv",
    "foldbot/TowelSpread-v0": "foldbot.envs.towel_flatten:TowelSpreadEnv",
    "foldbot/TowelFold-v0": "foldbot.envs.towel_fold:TowelFoldEnv",
    "foldbot/TowelFoldPair-v0": "foldbot.envs.towel_fold:TowelFoldPairEnv",
}
ENV_IDS = tuple(_ENTRY_POINTS)
"""The environments this package registers."""

for _id, _entry in _ENTRY_POINTS.items():
    if _id not in registry:
        register(id=_id, entry_point=_entry)

__all__ = [
    "ENV_IDS",
    "TowelFlattenConfig",
    "TowelFlattenEnv",
    "TowelFoldConfig",
    "TowelFoldEnv",
    "TowelFoldPairConfig",
    "TowelFoldPairEnv",
    "TowelSpreadConfig",
    "TowelSpreadEnv",
]
