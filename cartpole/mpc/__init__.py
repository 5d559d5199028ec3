"""Nonlinear MPC in the MuJoCo loop: multiple shooting on the exact discrete model, real-time iterations on a
condensed QP (:mod:`~cartpole.mpc.nmpc`, its compiled stage functions in :mod:`~cartpole.mpc.stage_functions`,
its settings as one value in :mod:`~cartpole.mpc.options`), and the IPOPT re-solve of the same NLP it is
benchmarked against (:mod:`~cartpole.mpc.ipopt_baseline`)."""
from cartpole.mpc.nmpc import NMPCController, NMPCError, nmpc_swingup
from cartpole.mpc.options import MPCOptions

__all__ = ["MPCOptions", "NMPCController", "NMPCError", "nmpc_swingup"]
