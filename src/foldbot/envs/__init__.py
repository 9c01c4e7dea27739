"""Gymnasium environments over the simulated cell (the optional `envs` extra: gymnasium).

- `towel_flatten`: TowelFlatten, a crumpled towel flattened by pick-and-place from RGB-D.
- `episode_process`: one episode's simulation in a fresh child process (Bullet's soft-body
  state is process-global, so a seed reproduces only as the first simulation in its process).

`import foldbot.envs` registers the environments with Gymnasium:
`gymnasium.make("foldbot/TowelFlatten-v0")`.
"""

from __future__ import annotations

try:
    from gymnasium.envs.registration import register, registry
except ImportError as exc:  # the optional extra is not installed
    raise ImportError(
        "foldbot.envs needs Gymnasium, the optional `envs` extra: pip install -e '.[envs]' "
        "(make install-test includes it)"
    ) from exc

from foldbot.envs.towel_flatten import TowelFlattenConfig, TowelFlattenEnv

ENV_IDS = ("foldbot/TowelFlatten-v0",)
"""The environments this package registers."""

if ENV_IDS[0] not in registry:
    register(id=ENV_IDS[0], entry_point="foldbot.envs.towel_flatten:TowelFlattenEnv")

__all__ = ["ENV_IDS", "TowelFlattenConfig", "TowelFlattenEnv"]
