"""The swing-up planner's settings as one value: :class:`PlanOptions`, what
:func:`cartpole.planning.trajopt.trajopt_swingup` takes (``replace``, ``as_dict`` and by-name variation from
:class:`cartpole.options.StageOptions`)."""
from __future__ import annotations

import dataclasses
from typing import ClassVar

from cartpole.ocp.bounds import OCPError
from cartpole.options import StageOptions

#: Fraction of each actuator's half ctrl range the exact discrete plan leaves free on both sides, so TVLQR keeps
#: authority to correct errors where the plan would otherwise ride the limit (0 when that is infeasible).
U_MARGIN = 0.05
#: Longest plan accepted, s (a swing-up plan is seconds long; far longer ones only make huge problems).
MAX_PLAN_T = 60.0
#: Collocation intervals of a plan whose ``N`` is not given (except ``dmc_*`` rewards: one per MJCF step).
DEFAULT_N = 100
#: Most collocation intervals a plan may have (its NLP grows with them; the default is about 100).
MAX_PLAN_N = 2000
#: Most starts (initial guesses) a plan may try.
MAX_PLAN_STARTS = 100
#: NLP solvers of the plan's last stage.
PLAN_SOLVERS = ("auto", "ipopt", "fatrop", "sqp", "ddp")


class PlanOptionsError(OCPError, ValueError):
    """Planner settings that cannot work (a negative margin, an unknown solver, a mesh of fewer than 2 intervals,
    an unknown field)."""


@dataclasses.dataclass(frozen=True, eq=False)
class PlanOptions(StageOptions):
    """Settings of the swing-up planner (:func:`cartpole.planning.trajopt.trajopt_swingup`), validated on creation.

    Attributes
    ----------
    objective : str, callable, Objective or None
        ``effort`` (None: the default, minimum ``integral u'u dt`` for T), ``time`` (the minimum-time plan itself),
        ``tracking`` (quadratic toward ``x*``, weights ``Q``, ``R``), ``dmc_swingup`` (dm_control's smooth reward,
        maximised), ``"MODULE:FUNCTION"`` or a function ``(x, u) -> scalar`` of CasADi symbols (a cost); see
        :mod:`cartpole.ocp.objectives`. Names are checked against the model when the planner runs.
    T : float or None
        Plan duration in s; None: ``(1 + time_margin) * T_min`` (``effort``), ``T_min`` (``time``) or
        ``T_min + RUNNING_HOLD`` (the running objectives), ``T_min`` from a minimum-time solve.
    N : int or None
        Collocation intervals (>= 2); None: 100, except ``dmc_swingup``: one interval per MJCF step.
    time_margin : float
        Relative margin (>= 0, dimensionless) on the minimum time when T is chosen automatically (0.2: 20 %).
    cart_margin : float
        Distance in m (>= 0) kept from each end of the slide range.
    u_margin : float
        Fraction in [0, 1) of each actuator's half ctrl range the exact discrete plan keeps free for feedback
        (default :data:`U_MARGIN`, 5 %).
    solver : {'auto', 'ipopt', 'fatrop', 'sqp', 'ddp'}
        NLP solver of the plan's last stage; ``auto`` (default): the one measured fastest, ``sqp`` unless
        ``solver_options`` (IPOPT's) are given, else IPOPT; ``sqp``: the last stage (any objective, ``time`` by its
        time scale) and the minimum-time refinement before it by :class:`~cartpole.solvers.sqp.CollocationSQP`, IPOPT
        when it does not converge (the coarse minimum-time multi-start stays IPOPT's); ``ddp``: the last stage by
        box-DDP on the exact discrete step (:mod:`cartpole.planning.ddp_plan`; every objective, ``time`` by a search
        over T of fixed-T solves; ``N`` is then ``T`` over the step), IPOPT when it does not converge.
    solver_options : mapping or None
        Passed straight to ``casadi.nlpsol`` (stored read-only).
    starts : int or None
        Guesses (>= 1) of the minimum-time multi-start (:func:`~cartpole.planning.trajopt.minimum_time`); None: the
        default shapes to the nearest upright angles.
    exact_discrete : bool or "auto"
        Re-solve the plan on the exact discrete model at the MJCF step and track that (True), never (False), or
        when TVLQR's predicted tracking strays more than :data:`~cartpole.planning.trajopt.TRACK_TOL` ("auto").
    Q, R : arrays or None
        Tracking and catch weights (nx, nx) and (nu, nu), read-only; None: :func:`cartpole.riccati.default_weights` of the
        model (1 per slide, 10 per hinge angle, 0.1 per rate, 0.1 per input).
    Qf : (nx, nx) array or None
        TVLQR terminal cost; None: the catch's discrete cost-to-go (seamless hand-over).
    T_max : float
        s (> 0): the longest swing-up the pumping search tries when the minimum-time multi-start finds none
        (:func:`~cartpole.planning.pumping.pumping_search`; default :data:`~cartpole.planning.pumping.T_MAX`).
    search_s : float or None
        s (> 0): wall-time budget of that pumping search (default 180); when it is spent the planner reports the
        longest T it tried. None: no wall-time budget, the search bounded by ``T_max`` and ``pump_restarts`` alone,
        so that it tries the same guesses on any machine at any load (its outcome then depends only on the CPU's
        round-off), at the cost of an unbounded wait.
    pump_restarts : int
        Guesses (>= 1) of the pumping search per duration (default 2: the first push either way; 3 adds one under a
        relaxed bound, more add seeded random ones).
    pump_seed : int
        Seed (>= 0) of the pumping search's random restarts.

    Raises
    ------
    PlanOptionsError
        A value outside the ranges above (shapes are checked against the model when the planner runs).
    """

    objective: object = None
    T: float | None = None
    N: int | None = None
    time_margin: float = 0.2
    cart_margin: float = 0.1
    u_margin: float = U_MARGIN
    solver: str = "auto"
    solver_options: object = None
    starts: int | None = None
    exact_discrete: object = "auto"
    Q: object = None
    R: object = None
    Qf: object = None
    T_max: float = 40.0
    search_s: float | None = 180.0
    pump_restarts: int = 2
    pump_seed: int = 0

    error: ClassVar[type] = PlanOptionsError
    SCALARS: ClassVar[tuple] = ("T", "N", "time_margin", "cart_margin", "u_margin", "starts", "T_max", "search_s",
                                "pump_restarts", "pump_seed")

    def __post_init__(self):
        self.number("T", low=0.0, low_open=True, high=MAX_PLAN_T, unit="s", optional=True)
        self.number("T_max", low=0.0, low_open=True, high=MAX_PLAN_T, unit="s")
        self.number("search_s", low=0.0, low_open=True, unit="s", optional=True,
                    hint="give `search_s=None` for no wall-time budget")
        self.number("pump_restarts", low=1, integer=True)
        self.number("pump_seed", low=0, integer=True)
        self.number("N", low=2, high=MAX_PLAN_N, integer=True, optional=True)
        self.number("time_margin", low=0.0, high=10.0)
        self.number("cart_margin", low=0.0, unit="m")
        self.number("u_margin", low=0.0)
        if not self.u_margin < 1.0:
            raise PlanOptionsError(f"u_margin = {self.u_margin} must be a fraction in [0, 1) of each half ctrl "
                                   "range.")
        self.number("starts", low=1, high=MAX_PLAN_STARTS, integer=True, optional=True)
        if self.solver not in PLAN_SOLVERS:
            raise PlanOptionsError(f"Solver '{self.solver}' is not supported; choose one of "
                                   f"{', '.join(PLAN_SOLVERS)}.")
        if not (self.exact_discrete == "auto" or isinstance(self.exact_discrete, bool)):
            raise PlanOptionsError(f"exact_discrete = {self.exact_discrete!r} must be True, False or 'auto'.")
        ok = (self.objective is None or isinstance(self.objective, str) or callable(self.objective)
              or isinstance(getattr(self.objective, "name", None), str))
        if not ok:
            raise PlanOptionsError(f"Objective {self.objective!r} is neither a name nor a function (x, u) -> "
                                   "scalar.")
        self.freeze_mapping("solver_options")
        for name in ("Q", "R", "Qf"):
            self.freeze_array(name)
