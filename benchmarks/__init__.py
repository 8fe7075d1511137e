"""Speed and expert benchmarks, run from a checkout (not installed): ``python -m benchmarks.speed``,
``benchmarks.train_speed``, ``benchmarks.experts``, ``benchmarks.sawyer_experts``, ``benchmarks.mail_bench``.
The harness that trains agents on suites is the installed package :mod:`lfd_bench`."""
