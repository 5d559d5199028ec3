"""Solvers of the collocation NLP beyond IPOPT and fatrop: an SQP whose QPs are condensed onto the knot controls and
solved by DAQP, qrqp or HPIPM (:mod:`~cartpole.solvers.sqp`, its compiled QP assembly in
:mod:`~cartpole.solvers.sqp_functions`). Iterative LQR / DDP belongs here too."""
from cartpole.solvers.sqp import CollocationSQP, SQPError

__all__ = ["CollocationSQP", "SQPError"]
