"""Solvers beyond IPOPT and fatrop: an SQP for the collocation NLP whose QPs are solved by Riccati recursions in C,
DAQP on the condensed QP behind them (:mod:`~cartpole.solvers.sqp`, its compiled QP assembly in
:mod:`~cartpole.solvers.sqp_functions`, the Riccati QP in :mod:`~cartpole.solvers.riccati_qp`), and control-limited
iterative LQR / DDP on the exact discrete model with state constraints by augmented Lagrangian
(:mod:`~cartpole.solvers.ddp`)."""
from cartpole.solvers.ddp import DDP, DDPError, DDPOptions, DDPResult, ddp_for_model
from cartpole.solvers.sqp import CollocationSQP, SQPError

__all__ = ["DDP", "DDPError", "DDPOptions", "DDPResult", "ddp_for_model", "CollocationSQP", "SQPError"]
