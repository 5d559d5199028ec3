"""The benchmarks ``cartpole bench`` and the scripts under ``benchmarks/`` run: trajectory optimisation against naive
``casadi.Opti`` (:mod:`~cartpole.apps.bench.trajopt`), NMPC against IPOPT re-solves (:mod:`~cartpole.apps.bench.mpc`),
batched MuJoCo replay against a plain loop (:mod:`~cartpole.apps.bench.replay`), the model build and exact ``A, B``
against MuJoCo's finite differences (:mod:`~cartpole.apps.bench.model`) and the swing-up of the shipped 1-, 2- and
3-pole carts in a fresh process (:mod:`~cartpole.apps.bench.swingup_chains`), the collocation SQP's QP solvers on the
planner's problems (:mod:`~cartpole.apps.bench.sqp_backends`). The scripts are thin command-line
callers of these modules."""
