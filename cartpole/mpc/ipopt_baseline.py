"""The baseline a do-mpc or plain CasADi user gets: the same MPC problem re-solved by IPOPT every period.

:class:`IpoptMPC` is :class:`~cartpole.mpc.nmpc.NMPCController` with its real-time iteration replaced by a full
IPOPT solve (``casadi.nlpsol("ipopt")``, ``expand=True``: one SX graph, IPOPT's defaults) of the same
multiple-shooting NLP (same stages, cost, terminal weight, ctrl bounds and soft rail), from the previous solution
shifted by one period (the same shift). Used by :func:`cartpole.apps.bench.mpc.run_mpc_benchmark` as the speed
baseline; it is a controller too (same call shape, ``solve_ms``, ``failures``). An instant whose IPOPT status is
not a success applies IPOPT's returned iterate when it is finite, as do-mpc does, and appends the status to
``unconverged``; a non-finite one takes the documented safe action and is a failure.
"""
from __future__ import annotations

from cartpole.mpc.nmpc import NMPCController
from cartpole.mpc.ipopt_nlp import IpoptNLP


class IpoptMPC(NMPCController):
    """Nonlinear MPC by a full IPOPT solve each control instant (the baseline); arguments as
    :class:`~cartpole.mpc.nmpc.NMPCController` plus ``ipopt_options`` (dict, merged into ``{"ipopt.print_level": 0,
    "print_time": False, "ipopt.sb": "yes", "expand": True}``). ``iterations`` is ignored (IPOPT runs to its own
    tolerance); the first iterate is converged by one IPOPT solve when ``x0`` is given."""

    c_step_capable = False  # each instant is IPOPT's, never the compiled RTI step

    def __init__(self, *args, ipopt_options: dict | None = None, **kwargs):
        self._ipopt_options = dict(ipopt_options or {})
        self.last_stats: dict = {}
        super().__init__(*args, **kwargs)
        self.qp_solver = "ipopt"

    def _setup_solver(self) -> None:
        self._nlp = IpoptNLP(self.problem, self.functions.step_expr, self._ipopt_options)

    def _ipopt(self, x, S, U):
        out = self._nlp.solve(x, S, U)
        self.last_stats = self._nlp.stats
        return out

    def _solve_instant(self, x, S, U):
        S_new, U_new = self._ipopt(x, S, U)
        if not self.last_stats.get("success", False):
            # do-mpc applies what IPOPT returned; keep the record so the benchmark can say how often it happened
            self.unconverged.append(str(self.last_stats.get("return_status")))
        return S_new, U_new

    def reset(self) -> None:
        """As :meth:`NMPCController.reset`; also empties :attr:`unconverged`."""
        super().reset()
        self.unconverged: list[str] = []

    def _converge(self, x0, S, U, iters):
        S, U = self._ipopt(x0, self._align(x0, S), U)
        self.init_info = {"iterations": int(self.last_stats.get("iter_count", 0)),
                          "converged": bool(self.last_stats.get("success", False)), "step": float("nan"),
                          "method": "ipopt"}
        return S, U
