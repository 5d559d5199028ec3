"""What a solver call reports: :class:`SolveInfo` (one solve: status, iterations, objective, time) and
:class:`Attempt` (one try of a multi-start or of a stage of the swing-up planner). Shared by the collocation
(:mod:`cartpole.ocp.collocation`), the SQP (:mod:`cartpole.solvers.sqp`) and the planner
(:mod:`cartpole.planning`)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SolveInfo:
    """What the NLP solver reported.

    Attributes
    ----------
    status : str
        The solver's return status (e.g. IPOPT's ``Solve_Succeeded``).
    success : bool
    iterations : int
    objective : float
        In physical units and the user's sign: ``integral u'u dt`` (ctrl^2 s) for ``effort``, the final time T
        (s) for ``time``, the running cost's integral for ``tracking`` and cost functions, the reward's integral
        (higher is better) for ``dmc_swingup`` and :func:`~cartpole.ocp.objectives.reward` functions.
    solve_time_s : float
        Wall time of the solver call in s.
    solver : str
        ``ipopt``, ``fatrop``, ``sqp`` or ``ddp`` (:mod:`cartpole.planning.ddp_plan`: then ``iterations`` are DDP
        iterations over every augmented-Lagrangian round).
    T : float
        Duration of the plan in s.
    start : int
        Index of the initial guess (start) the returned solution came from.
    guess : str
        Name of that guess (:func:`cartpole.ocp.guess.named_guesses`; ``"given"`` for a caller's trajectory).
    attempts : tuple of Attempt
        Every solver call that led to this plan, in the order made (a multi-start's failures included; the
        pipeline's earlier stages too), each with its iterations, status and objective.
    """

    status: str
    success: bool
    iterations: int
    objective: float
    solve_time_s: float
    solver: str
    T: float
    start: int = 0
    guess: str = ""
    attempts: tuple = ()

    @property
    def total_iterations(self) -> int:
        """Iterations of every attempt (this solve's own when there is no attempt record)."""
        return sum(a.iterations for a in self.attempts) if self.attempts else self.iterations

    @property
    def total_solve_time_s(self) -> float:
        """Solver wall time of every attempt in s (this solve's own when there is no attempt record)."""
        return sum(a.solve_time_s for a in self.attempts) if self.attempts else self.solve_time_s


@dataclass(frozen=True)
class Attempt:
    """One solver call of a multi-start or of one stage of the swing-up pipeline.

    Attributes
    ----------
    stage : str
        What was solved (e.g. ``"time"`` for a minimum-time problem, ``"effort"``).
    guess : str
        Name of the initial guess.
    N : int
        Collocation intervals.
    status : str
        The solver's return status.
    success : bool
    iterations : int
    objective : float
        As :attr:`SolveInfo.objective` (user's sign and units).
    T : float
        Duration in s of the solution (the guess's T when a free-time solve failed).
    solve_time_s : float
        Wall time of the solver call in s.
    chosen : bool
        This attempt's solution was kept (the best of its multi-start).
    """

    stage: str
    guess: str
    N: int
    status: str
    success: bool
    iterations: int
    objective: float
    T: float
    solve_time_s: float
    chosen: bool = False

    @classmethod
    def of(cls, info: "SolveInfo", stage: str, guess: str, N: int, *, chosen: bool = False) -> "Attempt":
        """The attempt that ``info`` (a solver call's :class:`SolveInfo`) reports, labelled ``stage``, ``guess``."""
        return cls(stage=stage, guess=guess, N=N, status=info.status, success=info.success,
                   iterations=info.iterations, objective=info.objective, T=info.T, solve_time_s=info.solve_time_s,
                   chosen=chosen)

    def as_dict(self) -> dict:
        """JSON-ready dict of the fields."""
        return {f: getattr(self, f) for f in self.__dataclass_fields__}
