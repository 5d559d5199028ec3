"""The NMPC's settings as one value: :class:`MPCOptions` (what :class:`cartpole.mpc.nmpc.NMPCController` and
:func:`cartpole.mpc.nmpc.nmpc_swingup` take; ``replace``, ``as_dict`` and by-name variation from
:class:`cartpole.options.StageOptions`)."""
from __future__ import annotations

import dataclasses
from typing import ClassVar

from cartpole.errors import CartPoleError
from cartpole.options import StageOptions

#: Control period in s when none is given (rounded to whole MJCF steps).
DEFAULT_PERIOD = 0.02
#: Prediction horizon in s when none is given (rounded to whole periods).
DEFAULT_HORIZON = 1.2
#: QP solvers the controller can use: DAQP (PyPI ``daqp``, dual active set, the default when installed) and
#: qpOASES (shipped with CasADi).
QP_SOLVERS = ("daqp", "qpoases")
#: The MPC's solvers: Gauss-Newton real-time iteration on the condensed QP, or warm-started box-DDP.
MPC_SOLVERS = ("rti", "ddp")
#: Default exact-penalty weight on the rail slack, cost per m (or rad) of violation.
RAIL_PENALTY = 1e3
#: Most prediction stages (horizon / period) an NMPC may have: its condensed QP grows with the square of the stages
#: and every control step solves one (the default is 60); a longer horizon or a shorter period is refused before
#: anything is built.
MAX_STAGES = 500
#: Most SQP (or DDP) iterations a control step may take, and the offline first iterate.
MAX_ITERATIONS = 100
MAX_INIT_ITERATIONS = 1000


def mpc_grid(options: MPCOptions, timestep: float) -> tuple[int, int]:
    """``(steps, N)``: MJCF steps per control period and prediction stages of ``options`` on a model stepping
    ``timestep`` s (the period rounded to whole steps, the horizon to whole periods), refused in one sentence when
    they cannot be used as given.

    Raises
    ------
    NMPCError
        A period shorter than half a physics step (it would round to a step it is not), a horizon shorter than one
        period, or more than :data:`MAX_STAGES` stages.
    """
    dt = float(timestep)
    period = DEFAULT_PERIOD if options.period is None else float(options.period)
    if period < 0.5 * dt:
        raise NMPCError(f"The NMPC's period {period:g} s is shorter than the MJCF's {dt:g} s physics step; give a "
                        f"whole number of steps (e.g. `period={dt:g}`).")
    steps = max(1, int(round(period / dt)))
    if options.horizon < 0.5 * steps * dt:
        raise NMPCError(f"The NMPC's horizon {options.horizon:g} s is shorter than its {steps * dt:g} s control "
                        "period; give a horizon of at least one period (e.g. `horizon=1.2`).")
    N = options.horizon / (steps * dt)
    if N > MAX_STAGES + 0.5:
        raise NMPCError(f"The NMPC's horizon {options.horizon:g} s at a {steps * dt:g} s period is {N:.3g} stages, "
                        f"more than the {MAX_STAGES} limit (each control step solves a QP over all of them); give "
                        f"at most `horizon={MAX_STAGES * steps * dt:g}` or a longer `period`.")
    return steps, max(1, int(round(N)))


class NMPCError(CartPoleError, ValueError):
    """Construction arguments of a nonlinear MPC that cannot work (period, horizon, weights, guess, state)."""


@dataclasses.dataclass(frozen=True, eq=False)
class MPCOptions(StageOptions):
    """Settings of the nonlinear MPC (:class:`~cartpole.mpc.nmpc.NMPCController`), validated on creation.

    Attributes
    ----------
    period : float or None
        Control period in s (> 0), rounded to a whole number (>= 1) of MJCF steps; None: the closed loop's period
        when it has one, else :data:`DEFAULT_PERIOD` (0.02 s).
    horizon : float
        Prediction horizon in s (> 0), rounded to whole periods (``N`` stages, >= 1); default 1.2 s.
    iterations : int
        Gauss-Newton SQP steps per control instant (>= 1; 1: real-time iteration).
    tol : float
        With ``iterations`` > 1: stop once a step changes no input by more than ``tol`` (ctrl units, >= 0);
        0: always ``iterations``.
    init_iterations : int
        Cap (>= 0) on the offline convergence of the first iterate for the start state (default 50).
    cart_margin : float
        m (>= 0) kept from each end of the cart's rail (default 0.1, as the offline plans).
    rail_penalty : float
        Exact-penalty weight (> 0) of the rail slack, cost per m (or rad) of violation (default
        :data:`RAIL_PENALTY`).
    Q, R : arrays or None
        Running weights per second on the state error (nx, nx) and on ``u - u*`` (nu, nu) (diagonals or scalars
        accepted; read-only); None: :func:`cartpole.riccati.default_weights`. Shapes are checked against the model.
    qp_solver : {'daqp', 'qpoases'} or None
        The condensed QP's solver; None: DAQP when installed, else qpOASES.
    prestabilize : bool or None
        The QP in steps relative to the Riccati feedback (True) or plain condensing (False); None: True when the
        fastest upright mode grows by more than :data:`~cartpole.mpc.nmpc.GROWTH_LIMIT` over the horizon.
    compiled : bool
        False evaluates the stage functions in CasADi's virtual machine (the fallback, same numbers).
    c_step : bool or None
        True: each control instant runs the compiled C of ``cartpole/csrc/nmpc.c.jinja`` (shift, linearisation,
        condensing, the dual active-set QP, the safe action: the C ``cartpole export`` ships,
        :mod:`cartpole.mpc.nmpc_c`); False: the Python step (CasADi stage functions, ``qp_solver``); None (default):
        the C step when ``compiled`` and no ``qp_solver`` is given. Without a C compiler the Python step runs (a
        note on stderr).
    solver : {'rti', 'ddp'}
        ``rti``: :class:`~cartpole.mpc.nmpc.NMPCController` (Gauss-Newton SQP steps on the condensed QP); ``ddp``:
        :class:`~cartpole.mpc.ddp_mpc.DDPMPCController` (``iterations`` warm-started box-DDP iterations a period;
        ``qp_solver``, ``prestabilize`` and ``tol`` do not apply).
    objective : str, callable or None
        What the MPC minimises over its horizon: None (or ``tracking``) the tracking of upright with ``Q``, ``R``
        (both solvers); with ``solver='ddp'`` also any running objective of the trajectory optimisation
        (``effort``, the ``dmc_*`` rewards, ``MODULE:FUNCTION``, a callable; :func:`cartpole.ocp.objectives.
        make_objective`), its seed plan planned for the same objective. ``time`` is not a running cost and is
        refused; so is any objective but tracking with ``rti``, whose Gauss-Newton QP needs a least-squares cost.
    seed_plan : bool
        With ``solver='ddp'``: True (default) plans the swing-up offline first
        (:func:`cartpole.planning.trajopt.trajopt_swingup`) and seeds the MPC with it; False plans nothing: the first
        solution is converged offline from ``u*`` (the equilibrium's input) and the MPC finds the swing-up itself in
        the loop, each shifted horizon extended by the upright LQR's input at its last predicted state,
        as MuJoCo MPC does (measured: the dm_control acrobot from its random starts, where an offline plan takes
        minutes a start; docs' NMPC page). The RTI NMPC tracks a plan and always has one.

    Raises
    ------
    NMPCError
        A value outside the ranges above.
    """

    period: float | None = None
    horizon: float = DEFAULT_HORIZON
    iterations: int = 1
    tol: float = 0.0
    init_iterations: int = 50
    cart_margin: float = 0.1
    rail_penalty: float = RAIL_PENALTY
    Q: object = None
    R: object = None
    qp_solver: str | None = None
    prestabilize: bool | None = None
    compiled: bool = True
    c_step: bool | None = None
    solver: str = "rti"
    objective: object = None
    seed_plan: bool = True

    error: ClassVar[type] = NMPCError
    SCALARS: ClassVar[tuple] = ("period", "horizon", "iterations", "tol", "init_iterations", "cart_margin",
                                "rail_penalty")

    def __post_init__(self):
        self.number("period", low=0.0, low_open=True, unit="s", optional=True)
        self.number("horizon", low=0.0, low_open=True, unit="s")
        self.number("iterations", low=1, high=MAX_ITERATIONS, integer=True)
        self.number("init_iterations", low=0, high=MAX_INIT_ITERATIONS, integer=True)
        self.number("tol", low=0.0)
        self.number("cart_margin", low=0.0, unit="m")
        self.number("rail_penalty", low=0.0, low_open=True)
        if self.solver not in MPC_SOLVERS:
            raise NMPCError(f"The MPC solver '{self.solver}' is not one of {', '.join(MPC_SOLVERS)}; give e.g. "
                            "`MPCOptions(solver='ddp')`.")
        if self.objective is not None:
            if not (isinstance(self.objective, str) or callable(self.objective)):
                raise NMPCError(f"The MPC objective {self.objective!r} is neither a name nor a function (x, u) -> "
                                "cost; give e.g. `objective='dmc_cartpole_swingup'`.")
            if self.objective == "time":
                raise NMPCError("The MPC cannot minimise time: it is not a running cost over a receding horizon; "
                                "give a running objective (tracking, effort, a dmc_* reward or MODULE:FUNCTION).")
            if self.solver == "rti" and self.objective != "tracking":
                raise NMPCError(f"The RTI NMPC's Gauss-Newton QP tracks upright (objective tracking, weights Q, R), "
                                f"not '{getattr(self.objective, '__name__', self.objective)}'; run it with "
                                "`MPCOptions(solver='ddp')`, which takes any running objective.")
        if self.seed_plan not in (True, False):
            raise NMPCError(f"seed_plan = {self.seed_plan!r} must be True or False.")
        self.set_field("seed_plan", bool(self.seed_plan))
        if not self.seed_plan and self.solver != "ddp":
            raise NMPCError("The RTI NMPC tracks an offline plan and cannot run without one; give "
                            "`MPCOptions(solver='ddp')` with `seed_plan=False`, or drop `seed_plan=False`.")
        if self.qp_solver is not None and self.qp_solver not in QP_SOLVERS:
            raise NMPCError(f"qp_solver '{self.qp_solver}' is not one of {', '.join(QP_SOLVERS)}.")
        if self.prestabilize is not None:
            if self.prestabilize not in (True, False):
                raise NMPCError(f"prestabilize = {self.prestabilize!r} must be True, False or None.")
            self.set_field("prestabilize", bool(self.prestabilize))
        if self.compiled not in (True, False):
            raise NMPCError(f"compiled = {self.compiled!r} must be True or False.")
        self.set_field("compiled", bool(self.compiled))
        if self.c_step not in (None, True, False):
            raise NMPCError(f"c_step = {self.c_step!r} must be True, False or None.")
        for name in ("Q", "R"):
            self.freeze_array(name)
