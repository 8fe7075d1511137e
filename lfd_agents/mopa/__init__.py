"""MoPA-RL: motion-planner-augmented reinforcement learning (SPEC §6).

* :class:`OMPLPlanner` -- joint-space planner (straight line, else OMPL RRT-Connect / RRT*),
  usable on its own with any ``is_valid(q)`` function.
* :class:`MoPAWrapper` -- Gymnasium wrapper giving an env with the planning interface the
  MoPA action space (direct small actions, planned large ones, k-step rewards).
* :class:`MoPASAC` / :class:`MoPATD3` -- SB3 agents with γ^k targets and path-segment reuse;
  per-task settings in :data:`MOPA_DEFAULTS`, :func:`make_mopa_env`, :func:`mopa_agent_kwargs`.
* :class:`MoPAAgent` -- harness adapter (``MoPASAC.for_benchmark``): budget in low-level steps,
  acts on the plain env one waypoint per step.
"""

from lfd_agents.mopa.agent import MoPAAgent
from lfd_agents.mopa.planner import OMPLPlanner, PlanResult
from lfd_agents.mopa.sac import (MOPA_DEFAULTS, MoPAReplayBuffer, MoPASAC, MoPATD3, make_mopa_env,
                                 mopa_agent_kwargs, smdp_targets)
from lfd_agents.mopa.wrapper import ActionMap, MoPAPlan, MoPAWrapper, invert_rescale, rescale_action

__all__ = [
    "OMPLPlanner", "PlanResult", "MoPAWrapper", "ActionMap", "rescale_action", "invert_rescale",
    "MoPASAC", "MoPATD3", "MoPAReplayBuffer", "MOPA_DEFAULTS", "make_mopa_env", "mopa_agent_kwargs",
    "smdp_targets", "MoPAPlan", "MoPAAgent",
]
