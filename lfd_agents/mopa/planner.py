"""Joint-space motion planning for MoPA.

The planner lives in the env package (:mod:`lfd_envs.mujoco.ompl_planner`, where OMPL is
imported), next to the envs' planning interface, because the scripted Sawyer experts plan with
it too; MoPA uses the same classes, re-exported here.
"""

from __future__ import annotations

from lfd_envs.mujoco.ompl_planner import PLANNER_ALGORITHMS, OMPLPlanner, PlanResult, densify, straight_line

__all__ = ["OMPLPlanner", "PlanResult", "PLANNER_ALGORITHMS", "straight_line", "densify"]
