"""The benchmarks ``cartpole bench`` and the scripts under ``benchmarks/`` run: trajectory optimisation against naive
``casadi.Opti`` (:mod:`~cartpole.apps.bench.trajopt`), NMPC against IPOPT re-solves (:mod:`~cartpole.apps.bench.mpc`)
and batched MuJoCo replay against a plain loop (:mod:`~cartpole.apps.bench.replay`)."""
