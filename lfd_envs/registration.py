"""Registers every lfd env with Gymnasium when ``lfd_envs`` is imported.

Gymnasium 1.x has no plugin entry points; ``gymnasium.make("lfd_envs:<Id>")`` imports this
package first, which registers everything below. Entry points are strings, so importing
``lfd_envs`` stays cheap (no Warp or MuJoCo import until an env is made).
"""

from __future__ import annotations

import gymnasium as gym

from lfd_envs.physics import FLEX_LIKE

_P = "lfd_envs.tasks"
_M = "lfd_envs.mujoco"

#: env id -> (entry point, vector entry point or None, default kwargs, max_episode_steps). For the MuJoCo
#: ids max_episode_steps is the default configuration's horizon; for the particle ids it is the longest
#: default horizon over the action modes (DryCloth and ThreeBoxes: 75 delta steps; their default
#: pick_place episodes last 3), see :func:`register_all`.
ENV_SPECS: dict[str, tuple[str, str | None, dict, int]] = {
    "StraightenRope-v0": (f"{_P}.rope:StraightenRopeEnv", f"{_P}.rope:StraightenRopeVectorEnv", {}, 75),
    "ClothFold-v0": (f"{_P}.cloth_fold:ClothFoldEnv", f"{_P}.cloth_fold:ClothFoldVectorEnv", {}, 100),
    "ClothFoldDiagonal-v0": (
        f"{_P}.cloth_fold_diagonal:ClothFoldDiagonalEnv", f"{_P}.cloth_fold_diagonal:ClothFoldDiagonalVectorEnv", {},
        100),
    "ClothFoldDiagonalPinned-v0": (
        f"{_P}.cloth_fold_diagonal:ClothFoldDiagonalEnv", f"{_P}.cloth_fold_diagonal:ClothFoldDiagonalVectorEnv",
        {"pinned": True}, 100),
    "ClothFoldDiagonalUnpinned-v0": (
        f"{_P}.cloth_fold_diagonal:ClothFoldDiagonalEnv", f"{_P}.cloth_fold_diagonal:ClothFoldDiagonalVectorEnv",
        {"pinned": False}, 100),
    "DryCloth-v0": (f"{_P}.dry_cloth:DryClothEnv", f"{_P}.dry_cloth:DryClothVectorEnv", {}, 75),
    "ThreeBoxes-v0": (f"{_P}.three_boxes:ThreeBoxesEnv", f"{_P}.three_boxes:ThreeBoxesVectorEnv", {}, 75),
    "Push2DObstacle-v0": (f"{_M}.push2d:Push2DObstacleEnv", None, {}, 400),
    "SawyerPushObstacle-v0": (f"{_M}.sawyer_push:SawyerPushObstacleEnv", None, {}, 250),
    "SawyerLiftObstacle-v0": (f"{_M}.sawyer_lift:SawyerLiftObstacleEnv", None, {}, 250),
    "SawyerAssemblyObstacle-v0": (f"{_M}.sawyer_assembly:SawyerAssemblyObstacleEnv", None, {}, 250),
    # SB3-friendly instruction tokens by default (the class default is the Text observation)
    "NistBoardInsert-v0": (f"{_M}.nist:NistBoardInsertEnv", None, {"instruction_encoding": "tokens"}, 100),
}

#: Engine settings of the ``-v1`` particle ids (the ``"flex_like"`` physics preset, see
#: :mod:`lfd_envs.physics`; read-only). ``sim_options`` given to ``gymnasium.make`` for a ``-v1``
#: id apply on top of these (``None`` turns a reference off).
FLEX_LIKE_SIM_OPTIONS = FLEX_LIKE.sim_options
#: ``-v1`` pick-and-place speed limit (m/s): MAIL's 1 cm per 10 ms frame.
FLEX_LIKE_PICK_PLACE_SPEED = FLEX_LIKE.pick_place_speed

#: the ``-v0`` particle-task specs (their ``-v1`` twins are built from them)
V0_PARTICLE_SPECS = {k: v for k, v in ENV_SPECS.items() if v[0].startswith(_P)}


def _with_physics(spec: tuple[str, str | None, dict, int], physics: str) -> tuple[str, str | None, dict, int]:
    entry, vec_entry, kwargs, horizon = spec
    return entry, vec_entry, {**kwargs, "physics": physics}, horizon


#: ``-v1`` ids: the ``-v0`` particle env classes with ``physics="flex_like"``
ENV_SPECS.update({v0.replace("-v0", f"-{FLEX_LIKE.version}"): _with_physics(spec, FLEX_LIKE.name)
                  for v0, spec in V0_PARTICLE_SPECS.items()})

PARTICLE_ENV_IDS = tuple(k for k, v in ENV_SPECS.items() if v[0].startswith(_P))
MUJOCO_ENV_IDS = tuple(k for k, v in ENV_SPECS.items() if v[0].startswith(_M))


def register_all() -> None:
    """Register every id in :data:`ENV_SPECS` (idempotent).

    Every spec has ``max_episode_steps``; the envs truncate at their own ``horizon`` as well.
    MuJoCo ids get :class:`~lfd_envs.core.time_limit.MatchHorizon`, which keeps ``gymnasium.make``'s
    ``TimeLimit`` at the horizon of the configuration actually made. Particle ids have vector
    entry points, which Gymnasium does not allow together with additional wrappers: their
    ``TimeLimit`` is the registered value, at least every default horizon of the task, so it only
    cuts an episode short for an explicit ``horizon`` above it (pass ``max_episode_steps`` then).
    """
    from lfd_envs.core.time_limit import MATCH_HORIZON

    for env_id, (entry, vec_entry, kwargs, horizon) in ENV_SPECS.items():
        if env_id in gym.registry:
            continue
        kwargs = {k: dict(v) if isinstance(v, dict) else v for k, v in kwargs.items()}  # specs own their dicts
        # Our envs enforce the contract themselves (and pass check_env); Gymnasium's
        # passive checker would only add per-step overhead.
        wrappers = () if vec_entry is not None else (MATCH_HORIZON,)
        gym.register(id=env_id, entry_point=entry, vector_entry_point=vec_entry, kwargs=dict(kwargs),
                     disable_env_checker=True, max_episode_steps=horizon, additional_wrappers=wrappers)
