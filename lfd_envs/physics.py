"""The physics presets of the particle tasks: ``"fast"`` (the ``-v0`` ids) and ``"flex_like"`` (``-v1``).

Every particle env takes ``physics=`` (default ``"fast"``) and says which it runs in
``env.unwrapped.physics``; the ``-v1`` ids are the ``-v0`` env classes registered with
``physics="flex_like"``. A preset replaces some engine settings of the task
(:class:`~lfd_envs.sim.SimParams` fields; the task's materials, radii and friction stay) and sets
the default pick-and-place speed limit. ``sim_options`` and ``pick_place_speed`` given to an env
apply on top of its preset; they do not change which preset it runs, so the scripted experts,
whose plans are tuned per preset, plan for the preset.

``flex_like`` is the physics built for fidelity to FleX (SoftGym, MAIL): pickers are sphere
colliders, the solver takes 20 substeps of one iteration per 10 ms frame without tethers,
self-collision keeps cloth and rope 1 cm thick at every resolution and is rebuilt every 10
substeps, and held pickers move at most 1 m/s in pick-and-place steps (MAIL's 1 cm per frame).
The solver follows the cloth's resolution so that it behaves about as at 40 particles per side
(``substeps_reference_resolution`` and ``bend_reference_resolution`` of
:class:`~lfd_envs.sim.SimParams`; the rules are described with the ``-v1`` physics in
``docs/particle_tasks.md``). ``fast`` changes nothing: the tasks' own settings (2 substeps of 5
iterations with tethers, pickers that pass through what they do not hold), on which every
committed ``-v0`` result was measured.

A state saved by ``get_state()`` belongs to one preset: its task identity is the env id of the
preset (``ClothFold-v0`` or ``ClothFold-v1``), and ``set_state`` refuses a state of the other.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Mapping

if TYPE_CHECKING:
    from lfd_envs.sim.params import SimParams

__all__ = ["PhysicsPreset", "FAST", "FLEX_LIKE", "PHYSICS_PRESETS", "DEFAULT_PHYSICS", "physics_preset"]


@dataclass(frozen=True)
class PhysicsPreset:
    """One physics preset of the particle tasks.

    Attributes:
        name: The ``physics`` argument that selects it (``"fast"``, ``"flex_like"``).
        version: Version suffix of the env ids registered with it (``"v0"``, ``"v1"``).
        sim_options: ``SimParams`` fields it sets on top of the task's (read-only).
        pick_place_speed: Default speed limit (m/s) of pickers that hold something in
            pick-and-place steps; None: the task's own schedule.
    """

    name: str
    version: str
    sim_options: Mapping[str, Any]
    pick_place_speed: float | None

    def sim_params(self, task_params: SimParams) -> SimParams:
        """``task_params`` (a task's ``SimParams``) with this preset's settings."""
        return dataclasses.replace(task_params, **self.sim_options)

    def env_id(self, task_name: str) -> str:
        """The env id of the task named ``task_name`` (its ``-v0`` id) under this preset, e.g.
        ``ClothFold-v1``; a name without the ``-v0`` suffix gets this preset's version added."""
        if self is FAST:
            return task_name
        base = task_name[:-len("-v0")] if task_name.endswith("-v0") else task_name
        return f"{base}-{self.version}"


#: the tasks' own settings (the ``-v0`` ids)
FAST = PhysicsPreset("fast", "v0", MappingProxyType({}), None)
#: FleX-like settings (the ``-v1`` ids), see the module docstring
FLEX_LIKE = PhysicsPreset(
    "flex_like", "v1",
    MappingProxyType({"substeps": 20, "iterations": 1, "tethers": False, "collision_passes": 0,
                      "self_collision_interval": 10, "picker_collision": True, "self_collision_distance": 0.01,
                      "substeps_reference_resolution": 40, "bend_reference_resolution": 40}),
    1.0)
#: ``physics`` name -> preset
PHYSICS_PRESETS: Mapping[str, PhysicsPreset] = MappingProxyType({p.name: p for p in (FAST, FLEX_LIKE)})
DEFAULT_PHYSICS = FAST.name


def physics_preset(physics: Any) -> PhysicsPreset:
    """The preset named ``physics``; ``ValueError`` naming the argument and the valid names."""
    from lfd_envs.core.errors import check_choice

    return PHYSICS_PRESETS[check_choice("physics", physics, PHYSICS_PRESETS)]
