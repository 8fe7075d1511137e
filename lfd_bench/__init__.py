"""The lfd benchmark harness: trains and evaluates agents on the suite's envs and writes the leaderboard.

- ``python -m lfd_bench.run --suite NAME`` (or the ``lfd-bench`` console script): run a suite's
  cells, one JSON record per (env, agent, seed) cell, resumable, then rewrite ``leaderboard.md``;
  results and the leaderboard go to the working directory unless ``--out``/``--leaderboard`` say
  otherwise.
- :mod:`lfd_bench.recipes`: named, versioned agent + demonstrator settings
  (``lfd_bench.recipes.load("dmfd/state-v0")``), referenced by the suites.
- Suites live in ``lfd_bench/configs/<name>.json``; the report is :mod:`lfd_bench.leaderboard`
  with :mod:`lfd_bench.stats` (seeds as runs, rliable) and :mod:`lfd_bench.plots`.
"""
