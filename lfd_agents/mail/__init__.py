"""MAIL — cross-morphology imitation: teacher demos with n pickers → student with m pickers.

``MAIL(student_env_id, teacher_dataset, workdir, student_kwargs, config).run()``; stages can be
run one at a time (``random_data``, ``dynamics``, ``convert``, ``student``) and resume from
their saved outputs. Command line: ``python -m lfd_agents.mail --help``.
"""

from lfd_agents.mail.agent import MAILAgent
from lfd_agents.mail.backends import LearnedBackend, SimulatorBackend
from lfd_agents.mail.cem import CEM, CEMConfig
from lfd_agents.mail.data import chamfer, collect_transitions, load_transitions, save_transitions
from lfd_agents.mail.dynamics import (DynamicsConfig, LearnedDynamics, ParticleDynamicsModel, subsample_indices,
                                      transitions_from_episodes)
from lfd_agents.mail.pipeline import MAIL, STAGES, MAILConfig

__all__ = ["MAIL", "MAILConfig", "MAILAgent", "STAGES", "CEM", "CEMConfig", "LearnedDynamics", "DynamicsConfig",
           "ParticleDynamicsModel", "LearnedBackend", "SimulatorBackend", "transitions_from_episodes",
           "subsample_indices", "collect_transitions", "save_transitions", "load_transitions", "chamfer"]
