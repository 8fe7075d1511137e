"""MoPA-RL: motion-planner-augmented reinforcement learning.

* :class:`OMPLPlanner` -- joint-space planner (straight line, else OMPL RRT-Connect / RRT*),
  usable on its own with any ``is_valid(q)`` function.
* :class:`MoPAWrapper` -- Gymnasium wrapper giving an env with the planning interface the
  MoPA action space (direct small actions, planned large ones, k-step rewards).
* :class:`MoPASAC` / :class:`MoPATD3` -- SB3 agents with γ^k targets and path-segment reuse;
  per-task settings in :data:`MOPA_DEFAULTS`, :func:`make_mopa_env`, :func:`mopa_agent_kwargs`.
* :class:`MoPAAgent` -- harness adapter (``MoPASAC.for_benchmark``): budget in low-level steps,
  acts on the plain env one waypoint per step.

Against MoPA-RL (clvrai/mopa-rl). The same as there: per-task reward scale, ω, Δq_MP, M, OMPL
range and invalid-target pull-back step (:data:`MOPA_DEFAULTS`); γ^k targets on k-step
transitions; reuse of up to M sub-segments of paths longer than 3 waypoints; and, through
:func:`mopa_agent_kwargs` (``MOPA_RL_SCHEDULE``, what the harness uses), a uniformly random
warm-up of 10k stored transitions (reuse included) without updates, then one gradient step
per stored transition, with timeouts stored as ``done``. The agent classes themselves default
to SB3's behaviour (``learning_starts`` in decisions, one update per decision, timeouts
bootstrapped). What differs, and why:

=========================  ==============================  ===================================  ==========================================
what                       MoPA-RL                         here                                 why
=========================  ==============================  ===================================  ==========================================
training budget            stored transitions (reuse       low-level env steps                  MoPA-SAC and SAC spend the same simulator
                           included)                                                            steps (the thesis's x axis)
OMPL search limit          1 s per query                   Push2D: 40k validity checks,         same success rate on a fixed seeded query
                                                           10 s cap; Sawyer: 1 s                set, failed searches stop sooner and the
                                                                                                same way on any machine; Sawyer not
                                                                                                measured (tools/mopa_planner_queries.py)
2D arm's unlimited joint   SO(2) subspace (wraps)          interval ±2π                         goals shifted by 2π solved none of the
                                                                                                34 failed queries of that set
state-space metric         L1 (compound space)             L2 (RealVectorStateSpace)            one OMPL space; ranges kept, not re-tuned
RRT-Connect path           raw waypoints, long segments    vertex shortcutting, straight        fewer low-level steps per planned action;
                           re-planned by a second          densification, whole path           every executed point is re-checked
                           planner                         re-checked (re-planned if not)
allowed penetration        1.5 mm (2D), 2 mm (Sawyer)      2 mm (the env's                      an env setting shared with the experts
                                                           ``planning_penetration``)
networks, init             actor 3×256, critics 2×256,     SB3's SAC (2×256 each, default       the same networks as the suite's plain
                           bias 0.1, last layer ±1e-3      init)                                SAC, so the learners differ only by MoPA
replay buffer              1e6                             1e5 (:class:`MoPAAgent`; pass        memory of a cell and its checkpoints
                                                           ``buffer_size``)
plain SAC baseline         reward scale 10                 SB3's SAC unchanged (scale 1)        the suite's SAC is one learner for all
                                                                                                tasks
evaluation actions         sampled (stochastic)            mean action                          the harness evaluates every learner so
=========================  ==============================  ===================================  ==========================================

The 2D task's own differences from MoPA-RL's pusher (servos instead of a velocity PID loop,
0.2 s steps) are in :mod:`lfd_envs.mujoco.push2d`.
"""

from lfd_agents.mopa.agent import MoPAAgent
from lfd_agents.mopa.planner import OMPLPlanner, PlanResult
from lfd_agents.mopa.sac import (MOPA_DEFAULTS, MOPA_RL_SCHEDULE, MoPAReplayBuffer, MoPASAC, MoPATD3,
                                 make_mopa_env, mopa_agent_kwargs, smdp_targets)
from lfd_agents.mopa.wrapper import ActionMap, MoPAPlan, MoPAWrapper, invert_rescale, rescale_action

__all__ = [
    "OMPLPlanner", "PlanResult", "MoPAWrapper", "ActionMap", "rescale_action", "invert_rescale",
    "MoPASAC", "MoPATD3", "MoPAReplayBuffer", "MOPA_DEFAULTS", "MOPA_RL_SCHEDULE", "make_mopa_env", "mopa_agent_kwargs",
    "smdp_targets", "MoPAPlan", "MoPAAgent",
]
