"""Diagnostics and doc-table generators, run from a checkout (not installed with the suite).

Each answers one question:

- ``python -m tools.docs``: regenerate the measured tables of README.md and docs/.
- ``python -m tools.demo``: what ``make demo`` runs (scene pictures, then the smoke suite).
- ``python -m tools.cloth_bounds``: how far cloth stretches where the engine is pushed hardest, -v0 against -v1?
- ``python -m tools.cloth_stretch``: how does cloth stretch depend on the solver's substeps and iterations?
- ``python -m tools.escapes``: do particles ever leave the scene under long random driving?
- ``python -m tools.mopa_modes``: which actions (planned or direct) does MoPA-SAC take while it trains?
- ``python tools/mopa_planner_queries.py``: do planner settings change the success rate on a fixed set of queries?
- ``python -m tools.online_probe``: what does the online phase of DMfD/AWAC do to the offline policy?
- ``python -m tools.offline_probe``: how well does the offline phase of DMfD/AWAC fit the demonstrations?
- ``python -m tools.trace_policy``: step by step, where does a learner depart from its demonstrator?
- ``python tools/frame_profile.py``: where does an engine frame spend its time, -v0 against -v1?
"""
