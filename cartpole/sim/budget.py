"""The work a MuJoCo command is about to do, estimated before it starts, and the budget it must stay within.

A file can make a routine command huge: a 5e-5 s time step turns the lab's five 6 s runs into 600 000 MuJoCo steps
(minutes of a Python controller in the loop), a long ``--duration`` at a fine step into hours, and a 1e-9 kg pole
into a mass matrix so ill-conditioned that no design on it means anything. So every command that runs MuJoCo first
adds up its physics steps (:func:`estimate_work`: duration / timestep x runs for each part of the work) and checks
them against a stated budget (:data:`DEFAULT_MAX_STEPS`, raised by the caller's ``max_steps``:
:func:`check_work`), and checks the model's conditioning at upright (:func:`check_conditioning`: the mass matrix's
condition number, and the lightest body against the heaviest), before any of it runs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cartpole.errors import CartPoleError

#: Physics steps a command may run in all before it refuses (its ``max_steps``; ``--max-steps`` on the command
#: line): minutes of MuJoCo with a Python controller in the loop. The lab's default run on the shipped 5 ms MJCF takes
#: 6 000 of them plus a 2 000-step video clip, the energy swing-up's catch basin 240 000 batched ones (counted a
#: tenth); at a 5e-5 s step the lab takes 800 000 (4.4 million if its starts must be shrunk) and the swing-up's basin
#: 24 million batched (counted 2.4 million).
DEFAULT_MAX_STEPS = 5_000_000

#: Work above this many physics steps is announced (one line on the progress reporter) before it starts.
ANNOUNCE_STEPS = 1_000_000

#: Largest condition number of the mass matrix at upright a model may have: beyond it the accelerations lose more
#: than half of double precision's digits, and the linearisation, the LQR and the plans mean nothing (the shipped
#: assets are below 1e3).
MAX_CONDITION = 1e8


class BudgetError(CartPoleError):
    """The work a command would do exceeds its budget of physics steps."""


class IllConditionedError(CartPoleError):
    """The model is numerically singular (its mass matrix at upright is too ill-conditioned to design on)."""


#: What a batched MuJoCo step (:func:`~cartpole.sim.batch.simulate_batch_linear`: MuJoCo's threaded rollout, the law
#: in numpy for the whole batch, as a catch basin's samples run) counts against the budget, in steps of a Python loop
#: (about ten times cheaper, :func:`~cartpole.validation.basin.catch_outcomes`).
BATCHED = 0.1


@dataclass(frozen=True)
class Work:
    """The physics steps of a command's parts, estimated before it runs.

    Attributes
    ----------
    timestep : float, s
        The MJCF's time step.
    parts : tuple of (str, int, float)
        What each part is (``"5 lab runs"``), its MuJoCo steps and what one of them counts against the budget (1 for
        a Python loop of ``mj_step``, :data:`BATCHED` for batched runs).
    plan : str
        The size of the plans the command solves besides (collocation intervals, variables, poles:
        :func:`plan_size`), empty when it plans nothing. Plans are bounded by their own limits (the planner's most
        intervals and poles), not by the budget of steps; the estimate says them so a long wait is explained.
    """

    timestep: float
    parts: tuple
    plan: str = ""

    @property
    def steps(self) -> int:
        """All the parts' physics steps."""
        return int(sum(p[1] for p in self.parts))

    @property
    def cost(self) -> float:
        """The steps as counted against the budget: each part's steps times its weight."""
        return float(sum(p[1] * p[2] for p in self.parts))

    def describe(self) -> str:
        """``"6e+03 MuJoCo steps at the 0.005 s time step (5 lab runs 6e+03)"``: the total and each part."""
        parts = "; ".join(f"{p[0]} {p[1]:.2g}" for p in self.parts if p[1])
        plan = f", and {self.plan}" if self.plan else ""
        return f"{self.steps:.2g} MuJoCo steps at the {self.timestep:g} s time step ({parts}){plan}"

    def to_dict(self) -> dict:
        """JSON form: ``steps``, ``cost`` (as counted against the budget), ``timestep`` (s), ``parts`` (``what``,
        ``steps``, ``weight`` each) and ``plan``."""
        return {"steps": self.steps, "cost": self.cost, "timestep": self.timestep,
                "parts": [{"what": p[0], "steps": p[1], "weight": p[2]} for p in self.parts], "plan": self.plan}


def plan_size(*, plans: int, intervals: int, nx: int, nu: int, poles: int) -> str:
    """The sentence part that states a command's plans' size: ``"2 plans of 100 collocation intervals (about 1.5e+03
    variables each) for 1 pole"``; empty for no plans.

    Parameters
    ----------
    plans : int
        How many plans the command solves (at most).
    intervals : int
        Collocation intervals ``N`` of each (Hermite-Simpson: a knot and a midpoint state per interval).
    nx, nu : int
        State and input sizes.
    poles : int
        Hinges of the chain.

    Returns
    -------
    str
    """
    if plans <= 0:
        return ""
    variables = (2 * int(intervals) + 1) * (int(nx) + int(nu)) + 1
    return (f"{plans} plan{'s' if plans != 1 else ''} of {int(intervals)} collocation intervals (about "
            f"{variables:.2g} variables each) for {poles} pole{'s' if poles != 1 else ''}")


def physics_steps(duration: float, timestep: float, runs: int = 1) -> int:
    """MuJoCo steps of ``runs`` runs of ``duration`` s each at ``timestep`` s (rounded up per run).

    Parameters
    ----------
    duration : float, s
    timestep : float, s
    runs : int

    Returns
    -------
    int
    """
    if duration <= 0 or runs <= 0:
        return 0
    return int(runs) * int(math.ceil(float(duration) / float(timestep) - 1e-9))


def estimate_work(parts, timestep: float, *, plan: str = "") -> Work:
    """The :class:`Work` of ``parts``, each ``(runs, seconds each, what)`` or ``(runs, seconds each, what, weight)``.

    Parameters
    ----------
    parts : iterable of tuples
        Runs, their simulated duration in s, what they are (for the sentences) and optionally what one of their steps
        counts against the budget (default 1; :data:`BATCHED` for batched runs).
    timestep : float, s
        The MJCF's time step.
    plan : str
        The plans' size (:func:`plan_size`), said beside the steps.

    Returns
    -------
    Work
    """
    out = []
    for part in parts:
        runs, seconds, what = part[:3]
        weight = float(part[3]) if len(part) > 3 else 1.0
        out.append((str(what), physics_steps(seconds, timestep, runs), weight))
    return Work(timestep=float(timestep), parts=tuple(out), plan=str(plan))


def check_work(work: Work, *, max_steps: float = DEFAULT_MAX_STEPS, option: str = "max_steps") -> Work:
    """Refuse, before it starts, work beyond ``max_steps`` physics steps (:attr:`Work.cost`: batched steps count
    :data:`BATCHED`).

    Parameters
    ----------
    work : Work
        From :func:`estimate_work`.
    max_steps : float
        The budget (default :data:`DEFAULT_MAX_STEPS`).
    option : str
        The name that raises the budget, in the sentence (the argument ``max_steps``; a command passes its flag).

    Returns
    -------
    Work
        ``work``, when within the budget.

    Raises
    ------
    BudgetError
        One sentence: the steps, what they are, the budget and the option that raises it.
    """
    if work.cost > float(max_steps):
        parts = "; ".join([f"{p[0]} {p[1]:.2g}" for p in work.parts if p[1]] + ([work.plan] if work.plan else []))
        batched = "" if work.cost == work.steps else f" (batched count a tenth: {work.cost:.2g})"
        raise BudgetError(f"At the {work.timestep:g} s time step this runs {work.steps:.2g} MuJoCo steps{batched}, "
                          f"beyond the budget of {float(max_steps):.2g}; give {option} {_round_up(work.cost)} to run "
                          f"it anyway ({parts}).")
    return work


def _round_up(steps: float) -> str:
    """``steps`` rounded up to two significant digits, as a command-line number (``6.2e+06``)."""
    if steps <= 0:
        return "1"
    e = math.floor(math.log10(steps)) - 1
    return f"{math.ceil(steps / 10 ** e - 1e-9) * 10 ** e:.2g}"


def conditioning(model) -> dict:
    """How well-conditioned a model is at upright: what :func:`check_conditioning` judges.

    Parameters
    ----------
    model : CartPoleModel

    Returns
    -------
    dict
        ``condition`` (the mass matrix's 2-norm condition number at ``x_eq``), ``fastest_mode_per_step`` (the largest
        ``|eigenvalue|`` of the continuous ``A`` at upright times the time step: far above 1 the model is stiff),
        ``lightest`` and ``heaviest`` (names of the moving bodies with the smallest and largest mass) and
        ``mass_ratio`` (their masses' ratio).
    """
    x_eq = np.asarray(model.x_eq, dtype=float)
    M = np.asarray(model.mass_matrix(x_eq), dtype=float)
    cond = float(np.linalg.cond(M)) if np.all(np.isfinite(M)) else float("inf")
    try:
        A, _ = model.linearize(x_eq, model.u_eq)
        fastest = float(np.abs(np.linalg.eigvals(np.asarray(A, dtype=float))).max()) * float(model.dt)
    except (np.linalg.LinAlgError, ValueError):
        fastest = float("inf")
    bodies = [b for b in model.params.bodies if b.mass > 0] or list(model.params.bodies)
    light = min(bodies, key=lambda b: b.mass)
    heavy = max(bodies, key=lambda b: b.mass)
    return {"condition": cond, "fastest_mode_per_step": fastest, "lightest": light.name, "heaviest": heavy.name,
            "lightest_mass": float(light.mass), "heaviest_mass": float(heavy.mass),
            "mass_ratio": float(light.mass) / float(heavy.mass) if heavy.mass > 0 else float("nan")}


def check_conditioning(model, *, max_condition: float = MAX_CONDITION) -> dict:
    """Refuse a model whose mass matrix at upright is numerically singular, naming the physics that makes it so.

    Parameters
    ----------
    model : CartPoleModel
    max_condition : float
        Largest condition number accepted (default :data:`MAX_CONDITION`).

    Returns
    -------
    dict
        :func:`conditioning`'s, when the model is accepted.

    Raises
    ------
    IllConditionedError
        One sentence: the lightest body's mass against the heaviest's (when that is the cause), the condition number
        and how much faster than the time step the fastest mode is, and the edit that fixes it.
    """
    c = conditioning(model)
    if c["condition"] <= float(max_condition):
        return c
    cond = f"condition number {c['condition']:.2g} of its mass matrix at upright, beyond {float(max_condition):.0e}"
    if c["mass_ratio"] < 1e-4:
        raise IllConditionedError(
            f"The mass of body '{c['lightest']}', {c['lightest_mass']:.3g} kg, is {c['mass_ratio']:.2g} of body "
            f"'{c['heaviest']}''s: the model is numerically singular ({cond}); give '{c['lightest']}' a mass of at "
            f"least {1e-4 * c['heaviest_mass']:.3g} kg in the MJCF.")
    stiff = (f"; its fastest mode is {c['fastest_mode_per_step']:.2g} times faster than the {model.dt:g} s step"
             if c["fastest_mode_per_step"] > 1 else "")
    raise IllConditionedError(
        f"The model is numerically singular ({cond}{stiff}); give its bodies masses and inertias (or its joints an "
        "armature) of comparable size in the MJCF.")
