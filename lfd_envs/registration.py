"""Registers every lfd env with Gymnasium when ``lfd_envs`` is imported.

Gymnasium 1.x has no plugin entry points; ``gymnasium.make("lfd_envs:<Id>")`` imports this
package first, which registers everything below. Entry points are strings, so importing
``lfd_envs`` stays cheap (no Warp or MuJoCo import until an env is made).
"""

from __future__ import annotations

import gymnasium as gym

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

#: Engine settings of the ``-v1`` particle ids, closer to FleX than the ``-v0`` defaults: pickers
#: are sphere colliders, the solver takes many small steps of one iteration without tethers
#: (stiff cloth at 40 per side without long-range attachments), self-collision is rebuilt every
#: 10 substeps and cloth and rope are 1 cm thick at every resolution. The solver follows the
#: cloth's resolution so that it behaves about as at 40 particles per side: finer cloth runs more
#: substeps (as stiff in stretch) and bend constraints of the same length in metres (spread
#: the way it is at 40), coarser cloth bends more easily (folds stay folded); see
#: ``substeps_reference_resolution`` and ``bend_reference_resolution`` of
#: :class:`~lfd_envs.sim.SimParams`. ``sim_options`` given to ``gymnasium.make`` for a ``-v1`` id
#: are applied on top of these (``None`` turns a reference off).
FLEX_LIKE_SIM_OPTIONS: dict = {"substeps": 20, "iterations": 1, "tethers": False, "collision_passes": 0,
                               "self_collision_interval": 10, "picker_collision": True,
                               "self_collision_distance": 0.01, "substeps_reference_resolution": 40,
                               "bend_reference_resolution": 40}
#: ``-v1`` pick-and-place speed limit (m/s): MAIL's 1 cm per 10 ms frame.
FLEX_LIKE_PICK_PLACE_SPEED = 1.0


_FLEX = "lfd_envs.flex_like"


def _flex_like(v0: str) -> tuple[str, str, dict, int]:
    entry, vec_entry, kwargs, horizon = ENV_SPECS[v0]
    return f"{_FLEX}:{entry.rpartition(':')[2]}", f"{_FLEX}:{vec_entry.rpartition(':')[2]}", kwargs, horizon


#: the ``-v0`` particle-task specs (their ``-v1`` twins are built from them)
V0_PARTICLE_SPECS = {k: v for k, v in ENV_SPECS.items() if v[0].startswith(_P)}
#: ``-v1`` ids: the ``-v0`` particle tasks, built by :mod:`lfd_envs.flex_like` (string entry points,
#: so specs serialise, e.g. into Minari datasets)
ENV_SPECS.update({v0.replace("-v0", "-v1"): _flex_like(v0) for v0 in V0_PARTICLE_SPECS})

PARTICLE_ENV_IDS = tuple(k for k, v in ENV_SPECS.items() if v[0].startswith((_P, _FLEX)))
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
