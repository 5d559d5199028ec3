"""Scored by the environments themselves: the dm_control suite's and Gymnasium's own episodes, run with the toolkit's
controllers, each return summed from the rewards the environment's own code pays.

``cartpole.ocp.dmc`` transcribes dm_control's rewards and starts so that the planner can optimise them; this module
runs the real thing. For each seed the environment is made and reset by its own code (dm_control's
``suite.load(domain, task, task_kwargs={"random": seed})``, Gymnasium's ``gymnasium.make(id).reset(seed=seed)``), the
start is read from its MuJoCo data (``qpos``, ``qvel``), a controller of the toolkit is built for that start (the
plan and its TVLQR and catch, the DDP MPC, or the LQR; :data:`ENVIRONMENTS` says which for each), and each of the
environment's steps applies ``u = controller(t, x)`` to the state the environment reached. The return is the sum of
the rewards ``env.step`` returned, over the episode the environment defines (dm_control's time limit, Gymnasium's
``max_episode_steps`` or its termination). The ctrl each step held is logged and replayed from the start in the
toolkit's own MuJoCo run of the same physics (:func:`cartpole.sim.replay` on the file named in :data:`ENVIRONMENTS`):
``replays`` says whether every state the environment reached is reproduced bit for bit.

dm_control and Gymnasium are optional dependencies (the ``envs`` extra); without them :class:`EnvScoreError` says what
to install.
"""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np

from cartpole._arrays import readonly
from cartpole.control import LinearFeedback
from cartpole.control.model_rollout import model_rollout
from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF, build_model
from cartpole.mpc.ddp_mpc import ddp_mpc_swingup
from cartpole.mpc.options import MPCOptions
from cartpole.ocp.dmc import rewards, task
from cartpole.planning.library import PlanLibrary, cached_library
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.planning.value_iteration import DMCReward, ValueIterationOptions, ValuePolicy, cached_hinge_values
from cartpole.sim import replay, simulate
from cartpole.supervise import SupervisorOptions, supervisor_for
from cartpole.supervise.supervisor import hinge_options

#: The folder of the toolkit's copies of dm_control's files (``cartpole/assets`` of the installed package).
#:
#: :meta hide-value:
ASSETS = SHIPPED_MJCF.parent


class EnvScoreError(CartPoleError):
    """An environment this module does not know, a bad seed or episode count, or dm_control/Gymnasium missing."""


@dataclass(frozen=True)
class Environment:
    """One environment scored in its own code.

    Attributes
    ----------
    name : str
        ``<domain>-<task>`` for dm_control (TD-MPC2's names), the Gymnasium id for Gymnasium.
    suite : str
        ``"dmc"`` or ``"gym"``.
    controller : str
        ``"trajopt"`` (the plan for ``objective``, its TVLQR and the catch), ``"mpc"`` (the DDP MPC on
        ``objective``'s planning surrogate, at the environment's control step, no offline plan; its horizon chosen
        among ``horizons``), ``"lqr"`` (the upright LQR designed over the environment's action hold) or ``"value"``
        (a pendulum driven at its hinge: the optimal policy of ``objective``'s exact reward by value iteration,
        :data:`VALUE_GRID`, the same for every start).
    objective : str or None
        The ``dmc_*`` objective planned for (:mod:`cartpole.ocp.dmc`).
    asset : str or None
        The toolkit's copy of the environment's file under ``cartpole/assets`` (dm_control); None: the
        environment's own file (Gymnasium's ``fullpath``).
    reference : float or None
        The best published learned agent's return on the task (TD-MPC2's best evaluation), None where none is
        quoted.
    reference_source : str
        Where ``reference`` comes from.
    horizons : tuple of float
        The DDP MPC's horizons in s (``"mpc"``). With more than one, each is run from the episode's start in the
        toolkit's own MuJoCo run of ``asset`` for the whole episode and scored with the task's exact reward
        (:func:`cartpole.ocp.dmc.rewards`); the one that earns most is the controller (:func:`best_mpc`). The
        environment's physics is that file's to the bit (``replays``), so its episode earns what was predicted.
    iterations : tuple of int
        DDP iterations a control step (``MPCOptions.iterations``) of further candidates, each with every horizon
        (``"mpc"``): run only from a start where the one-iteration MPC of every horizon predicts less than
        ``search_below`` (:func:`best_mpc`). Empty: none.
    search_below : float
        The predicted return below which the ``iterations`` candidates are searched too.
    """

    name: str
    suite: str
    controller: str
    objective: str | None = None
    asset: str | None = None
    reference: float | None = None
    reference_source: str = ""
    horizons: tuple = (2.0,)
    iterations: tuple = ()
    search_below: float = 0.0


#: The acrobot's DDP MPC horizons (s) tried from each start (:func:`best_mpc`): 2 s is the best single horizon
#: over dm_control's first ten episodes (docs/dmc.md); the longer ones swing up sooner from some starts near hanging,
#: where 2 s pumps for long.
ACROBOT_HORIZONS = (2.0, 2.5, 3.0, 4.0)
#: DDP iterations a control step of the acrobot's further candidates (each with every horizon of
#: :data:`ACROBOT_HORIZONS`), searched from the starts where no one-iteration horizon predicts
#: :data:`ACROBOT_SEARCH_BELOW` (:func:`best_mpc`): each is a different swing-up of the chaotic chain.
ACROBOT_ITERATIONS = (3, 2, 4)
#: The predicted return below which the acrobot's further candidates are searched: the starts near hanging, which
#: swing up late (docs/dmc.md); the others earn more and are left as they are (each candidate is a closed-loop
#: episode, tens of seconds).
ACROBOT_SEARCH_BELOW = 700.0

#: The value iteration's grid for a pendulum driven at its hinge (``"value"``): 400 x 401 nodes, where the returns
#: from dm_control's starts have stopped moving by more than a few steps (docs/dmc.md); made once (about a minute on
#: a loaded machine) and kept in the user cache under the model's hash (:func:`cartpole.planning.value_iteration.
#: cached_hinge_values`).
VALUE_GRID = ValueIterationOptions(angles=400, rates=401)

_TDMPC2 = "TD-MPC2's best evaluation (nicklashansen/tdmpc2, results/tdmpc2/<task>.csv)"

#: Every environment :func:`score_episode` runs, by name.
ENVIRONMENTS = {e.name: e for e in (
    Environment("pendulum-swingup", "dmc", "value", "dmc_pendulum_swingup", "dmc_pendulum.xml", 906.2, _TDMPC2),
    Environment("acrobot-swingup", "dmc", "mpc", "dmc_acrobot_swingup", "dmc_acrobot.xml", 711.5, _TDMPC2,
                horizons=ACROBOT_HORIZONS, iterations=ACROBOT_ITERATIONS, search_below=ACROBOT_SEARCH_BELOW),
    Environment("cartpole-swingup", "dmc", "trajopt", "dmc_cartpole_swingup", "dmc_cartpole.xml", 883.0, _TDMPC2),
    Environment("cartpole-swingup_sparse", "dmc", "trajopt", "dmc_cartpole_swingup_sparse", "dmc_cartpole.xml",
                849.0, _TDMPC2),
    Environment("cartpole-balance", "dmc", "lqr", "dmc_cartpole_balance", "dmc_cartpole.xml"),
    Environment("cartpole-balance_sparse", "dmc", "lqr", "dmc_cartpole_balance_sparse", "dmc_cartpole.xml"),
    Environment("InvertedPendulum-v5", "gym", "lqr"),
    Environment("InvertedDoublePendulum-v5", "gym", "lqr"),
)}


@dataclass(frozen=True)
class EpisodeScore:
    """One episode of an environment, run by its own code with a toolkit controller.

    Attributes
    ----------
    env : str
        The environment's name (:data:`ENVIRONMENTS`).
    seed : int
        The seed the environment was reset with.
    x0 : (nx,) array
        The start the environment's reset drew, ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    return_ : float
        The sum of the rewards the environment's ``step`` returned.
    steps : int
        Environment steps taken (fewer than the episode's length when Gymnasium terminated it).
    terminated : bool
        Gymnasium ended the episode by its termination rule (the pole fell); always False for dm_control.
    ctrl : (steps, nu) array
        The ctrl held over each environment step.
    x : (steps + 1, nx) array
        The state after each environment step, the start first.
    replays : bool
        Every state the environment reached is reproduced bit for bit by replaying ``ctrl`` from ``x0`` in the
        toolkit's MuJoCo run of ``mjcf``.
    warned : bool
        MuJoCo warned of a blown-up state during the episode (such a run is diverged, whatever it earned).
    design_s : float
        s of wall time spent building the controller for this start (the plan, the MPC's first solution).
    mjcf : str
        The file the controller was designed on and the replay ran.
    rewards : (steps,) array
        The reward the environment paid for each step.
    design : dict or None
        How the controller was chosen (:meth:`Chosen.as_dict`: the horizon, each candidate's predicted return), or
        the supervisor's summary (:meth:`cartpole.supervise.Supervisor.summary`), None for a controller made
        without a choice.
    """

    env: str
    seed: int
    x0: np.ndarray
    return_: float
    steps: int
    terminated: bool
    ctrl: np.ndarray
    x: np.ndarray
    replays: bool
    warned: bool
    design_s: float
    mjcf: str
    rewards: np.ndarray = field(default=None, repr=False)
    design: dict | None = None

    def as_dict(self) -> dict:
        """JSON-ready: ``env``, ``seed``, ``x0``, ``return``, ``steps``, ``terminated``, ``replays``, ``warned``,
        ``design_s``, ``mjcf``, ``design`` (the ctrl, states and rewards left out)."""
        return {"env": self.env, "seed": self.seed, "x0": [float(v) for v in self.x0],
                "return": round(float(self.return_), 4), "steps": self.steps, "terminated": self.terminated,
                "replays": self.replays, "warned": self.warned, "design_s": round(self.design_s, 3),
                "mjcf": self.mjcf, "design": self.design}


def environment(name: str) -> Environment:
    """The :class:`Environment` called ``name``; :class:`EnvScoreError` naming the known ones otherwise."""
    if name not in ENVIRONMENTS:
        raise EnvScoreError(f"Unknown environment '{name}'; choose one of {', '.join(ENVIRONMENTS)}.")
    return ENVIRONMENTS[name]


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise EnvScoreError(f"seed = {seed!r} must be a whole number >= 0 (the environment's reset seed).")
    return int(seed)


class _DMC:
    """A dm_control task behind one small interface: reset, state, step -> (reward, ended)."""

    def __init__(self, env: Environment, seed: int):
        try:
            from dm_control import suite
        except ImportError as exc:
            raise EnvScoreError(f"Scoring {env.name} needs dm_control ({exc}); install the envs extra: "
                                "pip install 'cartpole[envs]'.") from None
        domain, task = env.name.split("-", 1)
        self.env = suite.load(domain, task, task_kwargs={"random": seed})
        self.env.reset()
        self.physics = self.env.physics
        self.hold = 1  # physics steps per environment step (every task here: n_sub_steps = 1)
        self.length = None  # the episode ends when the task's TimeStep says it is the last
        self.mjcf = str(ASSETS / env.asset)

    def state(self) -> tuple[float, np.ndarray]:
        d = self.physics.data
        return float(d.time), np.concatenate([np.array(d.qpos, float), np.array(d.qvel, float)])

    def warned(self) -> bool:
        return bool(np.any(np.array(self.physics.data.warning.number) > 0))

    def step(self, u) -> tuple[float, bool]:
        ts = self.env.step(np.asarray(u, float))
        return float(ts.reward), bool(ts.last())


class _Gym:
    """A Gymnasium MuJoCo environment behind the same interface."""

    def __init__(self, env: Environment, seed: int):
        try:
            import gymnasium
        except ImportError as exc:
            raise EnvScoreError(f"Scoring {env.name} needs gymnasium with MuJoCo ({exc}); install the envs extra: "
                                "pip install 'cartpole[envs]'.") from None
        self.env = gymnasium.make(env.name)
        self.env.reset(seed=seed)
        self.raw = self.env.unwrapped
        self.hold = int(self.raw.frame_skip)
        self.length = int(self.env.spec.max_episode_steps)
        self.mjcf = str(self.raw.fullpath)

    def state(self) -> tuple[float, np.ndarray]:
        d = self.raw.data
        return float(d.time), np.concatenate([np.array(d.qpos, float), np.array(d.qvel, float)])

    def warned(self) -> bool:
        return bool(np.any(np.array(self.raw.data.warning.number) > 0))

    def step(self, u) -> tuple[float, bool]:
        _, reward, terminated, truncated, _ = self.env.step(np.asarray(u, float))
        self.terminated = bool(terminated)
        return float(reward), bool(terminated or truncated)


@dataclass(frozen=True)
class Chosen:
    """A controller picked among candidates by the return each earns in the toolkit's own MuJoCo run of the episode
    (:func:`choose`).

    Attributes
    ----------
    controller : callable
        ``u = controller(t, x)``, the chosen candidate (called as itself).
    choice : str
        Its label (the DDP MPC's horizon in s, for :func:`best_mpc`).
    predicted : dict
        Each candidate's label -> the return predicted for it (:func:`episode_return`).
    """

    controller: object
    choice: str
    predicted: dict

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) of the chosen controller at ``t`` (s) for the state ``x`` (nx,)."""
        return self.controller(t, x)

    def reset(self) -> None:
        """Restart the chosen controller (when it restarts: :func:`choose`'s candidates restart when called from
        ``t = 0`` too)."""
        if callable(getattr(self.controller, "reset", None)):
            self.controller.reset()

    @property
    def solve_ms(self) -> list:
        """The chosen controller's wall time per step (ms), when it keeps one (the DDP MPC); else empty."""
        return list(getattr(self.controller, "solve_ms", None) or ())

    def as_dict(self) -> dict:
        """JSON-ready: ``choice``, ``predicted`` (label -> predicted return) and ``predicted_return`` (the chosen
        one's)."""
        return {"choice": self.choice, "predicted": {k: round(r, 4) for k, r in self.predicted.items()},
                "predicted_return": round(self.predicted[self.choice], 4)}


def episode_return(model, mjcf: str, objective: str, controller, x0) -> float:
    """The return ``controller`` earns over one dm_control episode of the task ``objective`` from ``x0`` (nx,), in
    the toolkit's own MuJoCo run of ``mjcf`` (one ctrl per physics step, the task's time limit): dm_control's exact
    reward (:func:`cartpole.ocp.dmc.rewards`) of each state reached and ctrl held, summed. A run that diverges earns
    what it earned until then."""
    dt = float(model.dt)
    roll = simulate(mjcf, controller, x0, task(objective).steps(dt) * dt)
    x = np.column_stack([roll.qpos, roll.qvel])
    u = np.asarray(roll.ctrl, float).reshape(x.shape[0] - 1, model.nu)
    return float(np.sum(rewards(model, objective, x[1:], u)))


def choose(candidates: dict, model, mjcf: str, objective: str, x0) -> Chosen:
    """The candidate (label -> ``u = c(t, x)``, each restarting when called from ``t = 0``) that earns most over the
    episode of ``objective`` from ``x0`` (nx,) in the toolkit's MuJoCo run of ``mjcf`` (:func:`episode_return`; the
    first of equals, in the given order). dm_control's physics is that file's to the bit, so the environment's
    episode from ``x0`` earns the predicted return."""
    predicted = {str(k): episode_return(model, mjcf, objective, c, x0) for k, c in candidates.items()}
    best = max(predicted, key=lambda k: predicted[k])
    chosen = dict(zip(predicted, candidates.values()))[best]
    if hasattr(chosen, "reset"):
        chosen.reset()
    return Chosen(chosen, best, predicted)


def mpc_label(horizon: float, iterations: int = 1) -> str:
    """The label of the DDP MPC candidate with ``horizon`` (s) and ``iterations`` DDP iterations a control step:
    the horizon (``"2.5"``) for one iteration, ``"<horizon>x<iterations>"`` (``"2.5x3"``) for more."""
    return f"{float(horizon):g}" if int(iterations) == 1 else f"{float(horizon):g}x{int(iterations)}"


def _ddp_mpc(env: Environment, model, x0, period: float, horizon: float, iterations: int = 1):
    """The DDP MPC on ``env.objective`` from ``x0`` (no offline plan) with ``horizon`` s and ``iterations``."""
    opts = MPCOptions(solver="ddp", objective=env.objective, seed_plan=False, period=period, horizon=float(horizon),
                      iterations=int(iterations))
    return ddp_mpc_swingup(model.params, x0=x0, plan_model=model, options=opts)


def best_mpc(env: Environment, model, mjcf: str, x0, period: float):
    """The DDP MPC on ``env.objective`` (no offline plan, control period ``period`` s) from ``x0`` (nx,) that earns
    most over the episode (:func:`choose`): the controller itself when there is one horizon and no further
    iterations, else a :class:`Chosen` labelled by :func:`mpc_label`.

    The candidates are first the one-iteration MPC of each of ``env.horizons``; when none of them predicts
    ``env.search_below`` or more (a start from which they swing up late: near hanging), each horizon again with each
    of ``env.iterations`` DDP iterations a step. The chaotic chain makes every candidate a different swing-up, and
    the best of more of them is the better plan; the choice is among all of them, the first of equals in that
    order."""
    made = {mpc_label(h): _ddp_mpc(env, model, x0, period, h) for h in env.horizons}
    if len(made) == 1 and not env.iterations:
        return next(iter(made.values()))
    first = choose(made, model, mjcf, env.objective, x0)
    if not env.iterations or max(first.predicted.values()) >= env.search_below:
        return first
    more = {mpc_label(h, it): _ddp_mpc(env, model, x0, period, h, it) for it in env.iterations for h in env.horizons}
    second = choose(more, model, mjcf, env.objective, x0)
    winner = first if first.predicted[first.choice] >= second.predicted[second.choice] else second
    if winner is first and hasattr(first.controller, "reset"):
        first.controller.reset()
    return Chosen(winner.controller, winner.choice, {**first.predicted, **second.predicted})


def design(env: Environment, mjcf: str, x0, hold: int):
    """The toolkit's controller for ``env`` from the start ``x0`` (nx,), on the file ``mjcf``, for an environment
    that holds each action for ``hold`` physics steps: ``u = controller(t, x)`` (see :data:`ENVIRONMENTS`)."""
    model = build_model(mjcf)
    period = hold * float(model.dt)
    if env.controller == "lqr":
        return LinearFeedback.for_model(model, period=period if hold > 1 else None)
    if env.controller == "mpc":
        return best_mpc(env, model, mjcf, x0, period)
    if env.controller == "value":
        reward = DMCReward(model, env.objective)
        values = cached_hinge_values(model, reward, period=period if hold > 1 else None, options=VALUE_GRID)
        return ValuePolicy(values, model, reward)

    return trajopt_swingup(model.params, x0=tuple(x0), plan_model=model,
                           options=PlanOptions(objective=env.objective)).controller


#: The objective the supervisor plans for in each dm_control cart-pole environment (:func:`supervised`): the task's
#: own. On ``swingup_sparse`` the library keeps the box-entry plan (``exact``) and each plan in the loop keeps its
#: entry step (:func:`cartpole.planning.box_tail.box_tail_planner`: one IPOPT solve on the exact step), where the
#: planner's own route (the surrogate, then the box-entry search) takes 10-40 s a plan on the shared machine; the
#: smooth reward's plan enters the sparse box 0.3 s later than the entry plan (about 30 of the return).
SUPERVISOR_OBJECTIVES = {"cartpole-swingup": "dmc_cartpole_swingup",
                         "cartpole-swingup_sparse": "dmc_cartpole_swingup_sparse"}
#: The planning latency the supervisor predicts its first plan with (``SupervisorOptions.latency``), as a multiple of
#: the wall time of a warm plan measured just before the episode (:func:`supervised`; the supervisor's own factor
#: for its later plans, :attr:`cartpole.supervise.Supervisor.latency`): a plan that comes later than
#: predicted starts behind the state the energy law has reached, one that comes early waits for the predicted state
#: (the law pumping meanwhile), so erring long costs less.
LATENCY_MARGIN = 1.25
#: s of the catch's run on the model that certify a catch from a state outside its verified basin
#: (``SupervisorOptions.catch_rollout``) in Gymnasium's episodes, which end as soon as a pole falls: their starts lie
#: near upright, some outside the basin's conservative estimate but well within what the catch holds, and braking or
#: planning from them ends the episode (seeds 0 and 5 of InvertedDoublePendulum-v5).
GYM_CATCH_ROLLOUT = 2.0
#: How many times :func:`_rehearsed_latency` plans again from the state predicted over its latency so far.
REHEARSALS = 2


def supervised(env: Environment, mjcf: str, x0, hold: int, *, charged_latency: float | None = None,
               library: PlanLibrary | None = None, stepped: bool = False):
    """The toolkit's supervisor (:func:`cartpole.supervise.supervisor_for`: catch, swing-up law or plan, track,
    brake, chosen at run time) on the file ``mjcf``, its control period the environment's action hold of ``hold``
    physics steps: ``u = supervisor(t, x)``. Nothing is planned from ``x0`` before the episode (unlike
    :func:`design`): the supervisor plans in the loop, its planning wall time counted as latency in the episode's
    own time. The signature is :func:`design`'s (``controller`` of :func:`score_episode`).

    On dm_control's cart-poles (:data:`SUPERVISOR_OBJECTIVES`) it plans each swing-up (``cart_plans``), warm from the
    library of that model and objective (:func:`cartpole.planning.library.cached_library`: the plan from hanging at
    rest, planned cold once and kept in the user cache under the model's hash, never in the package; the sparse
    task's keeps its box-entry plan inside the box: ``exact``), from the knot of the stored plan (or its mirror image)
    nearest the state predicted when the plan will be ready (``warm_tails``), following the stored plan meanwhile
    (:class:`cartpole.supervise.lead_in.PlanLeadIn`, the energy law off it); TVLQR tracks the plan to its end, then the
    catch (the sparse task's plans: :func:`cartpole.planning.box_tail.box_tail_planner`). Before the episode the first
    plan is rehearsed from the library's own start (hanging at rest, not ``x0``) to build the solvers and measure the
    latency predicted for the first plan (:func:`_rehearsed_latency`; the supervisor's own rule for later plans is 1.25
    times the median of its measured ones).
    On dm_control's acrobot (the environments whose toolkit controller is the DDP MPC) every calm state, the start
    too, is swung up by the supervisor's swing-up MPC minimising the task's own objective (``env.objective``, as
    :func:`design`'s MPC; :func:`cartpole.supervise.supervisor.hinge_options`), the catch taking over in its basin:
    no plan unless the MPC fails.
    ``charged_latency`` (s): charge every plan that instead of its wall time (``SupervisorOptions.charged_latency``:
    a run that does not depend on the machine's speed, as a test needs); None (default) the measured wall time.
    ``library``: these plans instead of the cached library (a test's own).
    ``stepped``: the environment waits for each of the supervisor's actions, as dm_control's and Gymnasium's episodes
    do for any agent (a learned one's planning at each step is not timed either): every plan and design is charged no
    simulated time (``charged_latency=0``), and on the acrobot each take-over of the swing-up MPC designs it afresh
    from the state it takes over (:attr:`cartpole.supervise.Supervisor.mpc_design`: :func:`best_mpc`'s closed-loop
    choice among the environment's horizons and iterations, minutes of wall time, logged in the ``mpc`` decision's
    ``design_s``). False (default): planning is charged its wall time, as in a run in real time."""
    if stepped and charged_latency is not None:
        raise EnvScoreError("a stepped supervisor charges its planning no time; leave out charged_latency or stepped.")
    charged_latency = 0.0 if stepped else charged_latency
    model = build_model(mjcf)
    period = hold * float(model.dt) if hold > 1 else None
    objective = SUPERVISOR_OBJECTIVES.get(env.name)
    if objective is None and env.controller == "mpc":  # the acrobot: its swing-up MPC on the task's objective
        sup = supervisor_for(mjcf, model, period=period, plan=PlanOptions(objective=env.objective),
                             options=hinge_options(charged_latency=charged_latency, mpc_floor=None))
        if stepped:
            sup.mpc_design = functools.partial(best_mpc, env, model, mjcf, period=hold * float(model.dt))
        return sup
    if objective is None and env.suite == "gym":  # an episode that ends when a pole falls: catch what the catch holds
        return supervisor_for(mjcf, model, period=period, options=SupervisorOptions(
            charged_latency=charged_latency, catch_rollout=GYM_CATCH_ROLLOUT))
    if objective is None:
        return supervisor_for(mjcf, model, period=period)
    plan = PlanOptions(objective=objective, solver="ipopt")
    lib = (cached_library(model.params, model, starts=[model.x_hanging], options=plan, period=period,
                          exact=task(objective).sparse) if library is None else library)
    opts = SupervisorOptions(cart_plans=True, warm_tails=True, exact_plans=False, charged_latency=charged_latency)
    sup = supervisor_for(mjcf, model, period=period, plan=plan, options=opts, library=lib)
    if sup.planner is not None and charged_latency is None:
        latency = _rehearsed_latency(sup, model, lib.plans[0].x0)
        if latency is not None:
            sup.options = opts.replace(latency=latency)
    return sup


def _rehearsed_latency(sup, model, start) -> float | None:
    """s: the latency predicted for the first plan of ``sup``, rehearsed from ``start`` (nx,) (the library's own start,
    never the episode's) as the supervisor asks for a plan (``Supervisor._plan_request``): first from ``start``, then
    :data:`REHEARSALS` times from the state its meanwhile law (``sup.brake``) reaches from ``start`` over the latency
    predicted so far, each new prediction the mean of the last and :data:`LATENCY_MARGIN` times the plan's wall time
    (a plan from later on the stored plan is shorter and quicker: the mean settles between). Each plan is made twice and
    the second timed (the first builds what a plan of its length needs: the sparse task's entry problem is built once
    per length, seconds), and the last prediction's plan is built too, so that the episode's first plan finds its
    solvers made. When a plan fails, the prediction so far (None when the first fails)."""
    x, latency = np.asarray(start, dtype=float), None
    for k in range(REHEARSALS + 2):
        try:
            request, _ = sup._plan_request(x)
            sup._serve(request)
            if k == REHEARSALS + 1:
                return latency
            tic = time.perf_counter()
            sup._serve(request)
        except CartPoleError:  # e.g. predicted past the stored plan's end on a loaded machine
            return latency
        wall = LATENCY_MARGIN * (time.perf_counter() - tic)
        latency = wall if latency is None else 0.5 * (latency + wall)
        xs, _ = model_rollout(model, sup.brake, start, max(1, int(round(latency / model.dt))))
        x = xs[-1]
    return latency


#: The controllers :func:`score` can run, by name (``cartpole score --controller``): ``toolkit`` the one
#: :data:`ENVIRONMENTS` names for each environment, designed from the start (:func:`design`), ``supervisor`` the
#: supervisor, which decides in the loop, its planning charged its wall time (:func:`supervised`),
#: ``supervisor-stepped`` the same supervisor in an environment that waits for each action (``stepped=True``).
CONTROLLERS = {"toolkit": design, "supervisor": supervised,
               "supervisor-stepped": functools.partial(supervised, stepped=True)}


def score_episode(name: str, seed: int = 0, *, controller=None, max_steps: int | None = None) -> EpisodeScore:
    """Run one episode of the environment ``name`` from its own reset with ``seed``, with the toolkit's controller,
    and sum the rewards the environment pays.

    Parameters
    ----------
    name : str
        A key of :data:`ENVIRONMENTS` (``pendulum-swingup``, ``acrobot-swingup``, ``cartpole-swingup``,
        ``cartpole-swingup_sparse``, ``InvertedPendulum-v5``, ``InvertedDoublePendulum-v5``).
    seed : int
        The environment's reset seed (>= 0).
    controller : callable, optional
        ``controller(env, mjcf, x0, hold) -> u = c(t, x)`` instead of :func:`design` (a test's own, say).
    max_steps : int, optional
        Stop after this many environment steps (>= 1; default the whole episode): a shortened episode, its return
        the rewards paid so far.

    Returns
    -------
    EpisodeScore

    Raises
    ------
    EnvScoreError
        An unknown name, a bad seed, or dm_control/Gymnasium not installed.
    """
    env = environment(name)
    seed = _check_seed(seed)
    if max_steps is not None and (isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer))
                                  or max_steps < 1):
        raise EnvScoreError(f"max_steps = {max_steps!r} must be a whole number of environment steps >= 1.")
    run = _DMC(env, seed) if env.suite == "dmc" else _Gym(env, seed)
    if max_steps is not None:
        run.length = int(max_steps) if run.length is None else min(run.length, int(max_steps))
    _, x0 = run.state()
    tic = time.perf_counter()
    ctrl_of = (controller or design)(env, run.mjcf, x0, run.hold)
    design_s = time.perf_counter() - tic
    xs, us, rewards = [x0], [], []
    ended, warned = False, False
    try:
        while not ended and (run.length is None or len(us) < run.length):
            t, x = run.state()
            u = np.atleast_1d(np.asarray(ctrl_of(t, x), float))
            reward, ended = run.step(u)
            warned = warned or run.warned()
            us.append(u)
            rewards.append(reward)
            xs.append(run.state()[1])
    finally:  # a supervisor's planning worker ends with its episode, not when it is collected
        close = getattr(ctrl_of, "close", None)
        if callable(close):
            close()
    ctrl = np.array(us)
    again = replay(run.mjcf, x0, np.repeat(ctrl, run.hold, axis=0))
    replays = bool(np.array_equal(again.x[::run.hold], np.array(xs)))
    return EpisodeScore(env=name, seed=seed, x0=readonly(x0), return_=float(np.sum(rewards)), steps=len(us),
                        terminated=bool(getattr(run, "terminated", False)), ctrl=readonly(ctrl), x=readonly(np.array(xs)),
                        replays=replays, warned=warned, design_s=design_s, mjcf=run.mjcf,
                        rewards=readonly(np.array(rewards)),
                        design=_design_record(ctrl_of))


def _design_record(controller) -> dict | None:
    """What the episode's JSON keeps of how ``controller`` was made or decided: a :class:`Chosen`'s choice, a
    supervisor's summary (its decisions, plans and their wall times), else None."""
    if isinstance(controller, Chosen):
        return controller.as_dict()
    summary = getattr(controller, "summary", None)
    return summary() if callable(summary) else None


def score(name: str, n: int = 10, seed: int = 0, *, controller=None, on_episode=None,
          max_steps: int | None = None) -> dict:
    """``n`` episodes of ``name`` from the environment's resets with seeds ``seed, seed + 1, ...``.

    Parameters
    ----------
    name : str
        A key of :data:`ENVIRONMENTS`.
    n : int
        Episodes (>= 1).
    seed : int
        The first reset seed (>= 0).
    controller : callable, optional
        As :func:`score_episode`.
    on_episode : callable, optional
        Called with each :class:`EpisodeScore` as it is done (progress).
    max_steps : int, optional
        As :func:`score_episode`.

    Returns
    -------
    dict
        ``env``, ``seeds``, ``returns`` (one per seed), ``mean_return``, ``min_return``, ``reference`` and
        ``reference_source`` (the best published learned agent's), ``above_reference`` (the mean above it; None
        without one), ``all_replay``, ``any_warned``, ``episodes`` (:meth:`EpisodeScore.as_dict` each).
    """
    env = environment(name)
    seed = _check_seed(seed)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise EnvScoreError(f"n = {n!r} must be a whole number of episodes >= 1.")
    episodes = []
    for s in range(seed, seed + int(n)):
        ep = score_episode(name, s, controller=controller, max_steps=max_steps)
        episodes.append(ep)
        if on_episode is not None:
            on_episode(ep)
    returns = [round(float(e.return_), 4) for e in episodes]
    mean = float(np.mean(returns))
    return {"env": name, "seeds": list(range(seed, seed + int(n))), "returns": returns,
            "mean_return": round(mean, 4), "min_return": min(returns), "reference": env.reference,
            "reference_source": env.reference_source,
            "above_reference": None if env.reference is None else bool(mean > env.reference),
            "all_replay": all(e.replays for e in episodes), "any_warned": any(e.warned for e in episodes),
            "episodes": [e.as_dict() for e in episodes]}
