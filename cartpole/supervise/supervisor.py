"""A controller that swings up again whenever it is knocked down: catch, plan, track, brake, chosen at run time.

:class:`Supervisor` has the call shape of every controller, ``u = supervisor(t, x)``. Each call it decides:

* **catch**: inside the LQR catch's verified basin (``e' S e < rho``) the catch holds; it lets go only above
  ``release_factor * rho`` (hysteresis, as :class:`~cartpole.control.switching.SwitchingController`).
* **swing-up law**: on one pole driven by the cart, the energy-shaping law swings up from any state on its own
  where the motor is strong enough for it, so the supervisor need not plan (it is
  :class:`~cartpole.control.switching.SwitchingController` with its decisions logged; with ``cart_plans`` and a library
  it plans too, the law pumping meanwhile); a law that has not reached the catch within ``law_budget`` s hands over to
  the brake and the planner for the rest of the run. Likewise one pole driven at its hinge (a pendulum) with
  :func:`~cartpole.supervise.pump.hinge_swingup`.
* **brake**: with any hinge faster than ``calm_rate`` (or, with ``calm_energy``, the energy above it; for at most
  ``calm_budget`` s), a passive PD on the actuated joints (``u = u* - kp (q - q*) - kd q_dot`` on each driven joint)
  removes energy until the state is one the planner handles; passive, so it cannot add energy whatever the state.
  On a model driven at a hinge (the acrobot) :func:`supervisor_for` waits for the energy to reach the upright's (no
  plan is found from above it) and calms with :class:`~cartpole.control.drain.EnergyDrain` (``calm_drain``): its
  motor drives the elbow with its motion while it is slow and brakes it once fast, down to the upright's energy,
  where a damper on the elbow of a chain swinging as one body takes almost nothing out.
* **plan**: otherwise it plans a swing-up (``planner(x0) -> SwingupPlan``, warm-started from the nearest plan of
  its :class:`~cartpole.planning.library.PlanLibrary` when it has one) from the state predicted ``latency``
  seconds ahead through the model under the brake (the latency is the median planning time measured so far). The
  planner runs in a worker process killed at ``plan_budget`` (``plan_in_worker``, the default of
  :func:`supervisor_for` where the platform can fork: :mod:`cartpole.supervise.worker`; else in the caller's thread)
  and its wall time ``W`` is honest latency: the plan is used only from ``t + W`` of simulated time, the brake
  acting meanwhile; a plan later than predicted starts from its beginning when the state is still at its start
  (:data:`RESTART_RATE`; the brake holds a calm state), else it is tracked from where its clock has got to. The
  planner's own searches are bounded by ``plan_budget``. A plan that fails, or takes more than ``plan_budget`` s, is
  logged and retried after ``retry_after`` s of braking.
* **swing-up MPC**: with ``swingup_mpc`` (:func:`supervisor_for` sets it for a model driven at a hinge, the acrobot),
  a calm state (at most ``mpc_energy`` J above the upright's energy and, with ``mpc_floor``, at most that far below
  it; without, hanging at rest too: an MPC of a task's objective that pumps) is swung up by the DDP MPC
  (:class:`~cartpole.mpc.ddp_mpc.DDPMPCController`: ``mpc_iterations`` warm-started box-DDP iterations a control period
  (default one) on the exact discrete step, ``mpc_horizon`` s ahead (default :data:`MPC_HORIZON`), every step's wall
  time logged, bounded by ``mpc_step_budget``)
  instead of a plan: no planning latency, no funnel to leave (with ``mpc_converge`` its solution is first converged
  from the state predicted ``mpc_latency`` s ahead, the brake acting while that solve is charged; with
  :attr:`Supervisor.mpc_design` a new MPC is designed from that state at each take-over, charged alike). When the energy
  rises ``mpc_energy`` above the upright's (knocked again) an ``mpc_failed`` decision hands the state to the brake,
  and the MPC takes it again once calm; when the catch has not taken over within ``mpc_budget`` s, to the brake and
  the planner (below) until the next catch or knock (a calm state turned fast).
* **track**: TVLQR along the plan, handing over to the plan's catch at its end; a hinge that strays more than
  ``funnel`` rad from the plan means the plan is lost: plan again. With ``replan_every`` it re-plans as it goes:
  from the state predicted under the plan's TVLQR, warm-started from the rest of the plan, the old plan tracked
  until the new one is ready (a receding horizon, for plans TVLQR alone does not hold to their end).

Every decision is kept (:attr:`Supervisor.decisions`: time, kind, details) for the run's JSON.
"""
from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass
from typing import Callable, ClassVar, NamedTuple

import numpy as np

from cartpole.codegen import model_key
from cartpole.control import EnergyDrain, LinearFeedback
from cartpole.control.energy import EnergyShapingController, EnergyShapingModelError, check_single_pole
from cartpole.control.model_rollout import model_rollout
from cartpole.control.switching import SWINGUP_CATCH_R
from cartpole.errors import CartPoleError
from cartpole.mpc.ddp_mpc import DDPMPCController
from cartpole.mpc.options import MAX_ITERATIONS, MPCOptions
from cartpole.models import (CartPoleModel, Plant, build_model, planning_limits, plant_model, plant_params,
                             steps_per_period, wrap_angle)
from cartpole.options import OptionsError, StageOptions
from cartpole.ocp.dmc import is_sparse_task
from cartpole.planning.box_tail import box_tail_planner
from cartpole.planning.library import PlanLibrary, trajectory_tail
from cartpole.planning.options import PlanOptions
from cartpole.planning.trajopt import trajopt_swingup
from cartpole.sim.disturbance import joint_inertia_and_authority
from cartpole.supervise.lead_in import PlanLeadIn
from cartpole.supervise.pump import hinge_swingup, pendulum_driven_at_hinge
from cartpole.supervise.worker import PlanWorker, fork_available, run_within, timeout_sentence
from cartpole.validation import BasinCache


#: rad/s: a plan that comes later than predicted starts from its beginning when every hinge rate is still within this
#: of the plan's start (and every angle within half the funnel): the brake holds a calm state while the plan is made,
#: so a late plan is usually still right; else it is tracked from where its clock has got to.
RESTART_RATE = 1.0
#: s: how often :func:`supervisor_for` has a model driven at a hinge (the acrobot) re-plan while tracking
#: (``SupervisorOptions.replan_every``): TVLQR alone loses its long pumping plans part way, re-planned every 2 s from
#: the rest of the plan it swings up.
HINGE_REPLAN_EVERY = 2.0
#: Warm starts (the nearest knots' tails, one per stored plan or mirror image) a plan with ``warm_tails`` tries before
#: it fails, never cold: each try is one solve (seconds), a cold plan from such a state minutes.
WARM_TRIES = 3
#: The weight of an energy mismatch in the choice of knot (``PlanLibrary.knot_guesses``' ``energy_weight``): a tenth
#: of the swing-up's energy counts as much as 1 rad of hinge angle (at the lab's weight, 10 per rad^2). A calmed
#: acrobot has about the upright's energy: knots of the last pumps, short tails, not the plan from its first swing.
KNOT_ENERGY_WEIGHT = 31.6
#: s: the shortest tail of a stored plan a warm start is taken from (``knot_guesses``' ``min_tail``): matched by
#: energy alone a calmed acrobot's knot can be the plan's last, a quarter-second plan from a pose it does not have.
KNOT_MIN_TAIL = 2.0
#: J: :func:`supervisor_for` has a model driven at a hinge plan only at or below the upright's energy
#: (``SupervisorOptions.calm_energy``), and its energy drain (``calm_drain``) stops there: a plan from above the
#: upright's energy is not found (minutes of cold tries). Knocked down, dm_control's acrobot holds 13-32 J above it
#: (its swing-up needs 39 J; seeds 0-11 of ``Knockdown(3, 0.3)`` at the knock's end), which the drain and the
#: joints' damping take out in 0.7-6.3 s (median 1.3 s), the damping alone in 2.4-16.4 s (median 3.5 s; in MuJoCo,
#: ``tools/acrobot_drain.py``, ``docs/recovery.md``). A throw can leave far more; above about 100 J the 2 N m elbow
#: motor can hardly help: centrifugal torques hold the elbow straight (``tests/supervise/test_brake.py``).
HINGE_CALM_ENERGY = 0.0
#: s: the time constant of the brake :func:`supervisor_for` gives a model driven at a hinge below the drain's target
#: (``calm_brake_time``: within :data:`DRAIN_MARGIN` of the upright's energy or below, while the state is fast): on
#: the acrobot the default's stiff spring holds the elbow straight, so the chain swings as one body and its energy
#: leaves only by the shoulder's damping; a soft brake lets the elbow swing and damps it too (with the brake alone,
#: knocked by ``Knockdown(3, 0.3)``, seeds 2, 3, the energy reached the upright's 11-12 s sooner with 1.5 s than with
#: 0.15 s; median over seeds 0-11 1.4 s against 2.1 s: ``tools/acrobot_drain.py``). While a plan is on its way the
#: stiff brake holds the chain straight, near the plans' poses (with the soft one there, warm starts from the
#: swing-up's knots failed where they converged with the stiff one).
HINGE_BRAKE_TIME = 1.5
#: s: how long :func:`supervisor_for` lets the drain and brake calm a model driven at a hinge (``calm_budget``):
#: knocked, the acrobot reaches the upright's energy 0.7-6.3 s after the knock (above); from the highest energies a
#: throw could leave (hundreds of J: the damping halves the energy's excess over hanging in about 19 s) 120 s
#: leaves room.
HINGE_CALM_BUDGET = 120.0
#: s: the swing-up law (one pole driven by the cart) that has held every hinge at rest (below :data:`STALL_RATE`)
#: outside the catch's basin this long has stalled: a deterministic law gives a state at rest the same ctrl each step.
#: Gymnasium's and Brax's inverted pendulums (hinge limited to +-90 degrees) knocked down rest on their hinge's limit,
#: horizontal, where pushing the cart has no lever on the pole; a ``stalled`` decision says so once per fall and the
#: run's ``unreachable`` lists it (tests/supervise/test_unseen_models.py).
STALL_SECONDS = 2.0
#: rad/s: a hinge slower than this counts as at rest for :data:`STALL_SECONDS`.
STALL_RATE = 1e-2
#: rad: a hinge this close to (or beyond) an end of its range rests on that limit, which a stall's reason names.
STALL_LIMIT_TOL = 0.05
#: J: with ``calm_drain`` the energy drain stops this far above ``calm_energy`` and the calming brake takes the rest:
#: drained right down to the upright's energy the acrobot's elbow still swings hard (the drain throws it about), far
#: from the poses of the stored plans' knots, and its plans from there were lost and made again (measured with an
#: earlier knock that left 140-1450 J, seed 11 of ``Knockdown(3, 0.3)``: swung up 13 s and 27 s after calm; handed
#: to the soft brake 5 J above, as soon calm, and each plan from there swung up at once, 12 s and 10 s after calm).
#: The knock now leaves 13-32 J, so the drain acts on only its first 8-27 J (not re-measured without the margin).
DRAIN_MARGIN = 5.0
#: s: the horizon of the swing-up MPC (``swingup_mpc``): the DDP MPC's best single horizon on dm_control's acrobot
#: (docs/dmc.md). From the states a knock leaves the acrobot in once calmed (within 7 J below the upright's energy,
#: seeds 0, 1, 3, 9 of ``Knockdown(3, 0.3)``) it reached the catch's basin in 2.0-3.7 s, where the plans from the
#: same states (charged 2 s, tracked 5-12 s) were often lost or not found (``tools/acrobot_minute.py``).
MPC_HORIZON = 2.0
#: J: how far above the upright's energy the swing-up MPC takes a state over (``mpc_energy``), and lets go of it (an
#: ``mpc_failed`` decision: knocked again) once the energy rises above it; how far below, :data:`HINGE_MPC_FLOOR`.
#: With :func:`supervisor_for`'s ``calm_energy`` of 0 J (the MPC takes only calm states at or below the upright's
#: energy), what matters of it is the let-go: 35 J is most of a swing-up's energy, more than the MPC's own swings put
#: in.
HINGE_MPC_ENERGY = 35.0
#: J: how far below the upright's energy :func:`hinge_options` lets the swing-up MPC of the tracking objective take a
#: calm state over (``mpc_floor``): all but the lowest 4 J of the acrobot's swing-up energy (39 J). Calmed after a
#: knock it is 0-25 J below (the soft brake goes on while a hinge is still fast); with 20 J the calm states below it
#: were planned from, and of the three such knocks in seeds 0-11 one was never recovered and one only after its plans
#: were lost twice (``tools/acrobot_minute.py``); with 35 J the MPC swung each up. Near hanging the tracking MPC does
#: not swing up (dm_control's seeds 4 and 8: no catch in their 10 s episodes): those states are planned from, unless
#: the MPC minimises a task's objective (``supervisor_for``'s ``plan``), which pumps from hanging (``docs/dmc.md``):
#: then no floor.
HINGE_MPC_FLOOR = 35.0
#: s: the wall time predicted for converging the swing-up MPC's solution at a take-over (``mpc_converge``,
#: ``SupervisorOptions.mpc_latency``): from dm_control's acrobot starts (seeds 0-9) the 2 s MPC of
#: ``dmc_acrobot_swingup`` converged in 6-282 DDP iterations, 4-296 ms of CPU time; on a loaded machine its wall time
#: is several times that, charged as it is. Off by default: on dm_control's acrobot, converged at the take-over and
#: charged this long, it earned about what the MPC acting at once earns on seeds 0-9, more on seeds 10-19 and less on
#: seeds 20-32: chance, the chaotic chain's (docs/dmc.md, ``tools/acrobot_supervisor_gap.py``).
MPC_CONVERGE_LATENCY = 0.3


#: What :meth:`Supervisor.prepare` has warmed in this process: ``(model_key, exact_plans, warm_tails)`` of each.
_PREPARED: set = set()
_LOG = logging.getLogger(__name__)


class _Ask(NamedTuple):
    """What a plan was asked for with: the time ``t`` (s), the predicted start ``x_pred`` (nx,), the ``steps`` it
    was predicted over, the predicted latency ``lat`` (s), the library's distance ``dist`` to its warm start."""

    t: float
    x_pred: np.ndarray
    steps: int
    lat: float
    dist: float | None


class SupervisorError(OptionsError):
    """Bad supervisor settings (a budget, rate, funnel or factor that is not a positive number)."""


@dataclass(frozen=True, eq=False)
class SupervisorOptions(StageOptions):
    """The supervisor's settings.

    Attributes
    ----------
    plan_budget : float
        s of wall time one plan may take; a plan over it counts as failed (it is still measured and logged).
    latency : float
        s, the planning latency assumed before any plan has been timed (then the median of the measured ones).
    calm_rate : float
        rad/s: with any hinge faster than this the brake acts before planning.
    funnel : float
        rad: a hinge angle further than this from the plan being tracked means the plan is lost.
    release_factor : float
        The catch lets go above ``release_factor * rho`` (> 1).
    retry_after : float
        s of braking after a failed plan before the next try.
    brake_time : float
        s, the brake's time constant: ``kd = M_jj / brake_time``, ``kp = M_jj / brake_time^2`` per driven joint
        (``M_jj`` its joint-space inertia at upright), in ctrl units through the actuator's moment arm. The default
        0.15 s calms the shipped chains fastest of 0.05, 0.15 and 0.5 s (docs/recovery.md, measured from random
        states with rates up to 20 rad/s).
    charged_latency : float or None
        s of simulated time every plan is charged instead of its measured wall time (and assumed as the latency it
        is predicted over): a run reproducible on any machine, standing for one whose planner answers within that
        time (each plan's wall time is still logged beside it, and a plan over ``plan_budget`` still fails). None
        (default): the wall time, honest on the machine that runs it.
    calm_budget : float
        s: a state the brake has not calmed (some hinge still faster than ``calm_rate``) after this long is planned
        from as it is (the planner's own budget bounds the try), a ``calm_timeout`` decision saying so; braking
        starts again after a failed plan.
    exact_plans : bool
        Re-solve a plan on the exact discrete model as the plan options say (True, default: their
        ``exact_discrete``, "auto" unless given), or never (False: TVLQR tracks the collocation plan and absorbs the
        difference). On the two-pole cart the re-solve is worth its time (60 s of knockdowns: uptime 0.32 with it,
        0.27 without); on the acrobot it was two thirds of each plan (minutes) without converging, and without it
        TVLQR does not hold the acrobot on its plan either.
    replan_every : float or None
        s: while a plan is tracked, every this long a new plan is made from the state predicted ``latency`` s ahead
        under the plan's own TVLQR, warm-started from the rest of the plan being tracked (its remaining duration:
        the horizon shrinks, the mesh grows finer), and the old plan is tracked until the new one is ready; a re-plan
        that fails is logged (``replan_failed``) and the old plan kept. None (default): never, a plan is tracked to
        its end (:func:`supervisor_for` sets 2 s for a model driven at a hinge, the acrobot: TVLQR alone does not
        hold its long pumping plans).
    calm_brake_time : float or None
        s, the time constant of the brake that acts while the state is fast (calming it), or None (default): that of
        ``brake_time``, which acts otherwise (while a plan is on its way). :func:`supervisor_for` sets
        :data:`HINGE_BRAKE_TIME` for a model driven at a hinge.
    calm_energy : float or None
        J of total mechanical energy (:attr:`CartPoleModel.energy`, zero at upright rest) above which the state
        counts as fast as well (the brake acts, no plan is asked for), or None (default): rates alone. A chain driven
        at a hinge (the acrobot) knocked or thrown holds more than the upright's energy, which its motor
        (``calm_drain``) and its joints' damping remove (seconds after a knock, most of a minute from hundreds of J);
        a plan from above the upright's energy fails after minutes (:func:`supervisor_for` sets
        :data:`HINGE_CALM_ENERGY`).
    warm_tails : bool
        Warm-start each plan from the tail of a stored plan from its knot nearest the predicted start (mirror images
        too; :meth:`~cartpole.planning.library.PlanLibrary.knot_guesses`), the :data:`WARM_TRIES` nearest in turn and
        never cold (the planner is called ``planner(x0, guess=..., cold=False)``; a plan that fails is retried from
        the next predicted state; a re-plan while tracking is warm only too), instead of the stored plan from the
        nearest start (False, default). A calmed acrobot swings low, near a knot of the plan from hanging, not near
        its start.
    calm_drain : bool
        Calm with :class:`~cartpole.control.drain.EnergyDrain` (full ctrl with the driven joint while it is slow,
        against it once fast) down to :data:`DRAIN_MARGIN` J above ``calm_energy`` (0 J, the upright's, when that is
        None), the calming brake below it (True; :func:`supervisor_for` sets it for a model driven at a hinge), or
        with the calming brake alone (False, default): a passive damper on a driven joint the chain hardly moves takes
        little out.
    swingup_mpc : bool
        Swing a calm state up to ``mpc_energy`` J above the upright's energy up with the DDP MPC (module docstring)
        before any plan (True: :func:`supervisor_for` builds it, and sets it for a model driven at a hinge), or plan
        (False, default).
    mpc_energy : float
        J above the upright's energy up to which the swing-up MPC takes a calm state over; it lets go above it
        (knocked again) and takes the state again once calmed.
    mpc_floor : float or None
        J below the upright's energy down to which the swing-up MPC takes a calm state over (further below: planned
        from; default :data:`HINGE_MPC_FLOOR`), or None: however far below, hanging at rest too. :func:`supervisor_for`
        sets None when the MPC minimises a task's objective that pumps from hanging (``plan``'s objective): the
        tracking of upright does not swing the acrobot up from there.
    mpc_budget : float
        s the swing-up MPC may run without the catch taking over; then the brake and the planner, until the next catch
        or knock (a calm state turned fast).
    law_budget : float
        s the swing-up law (energy shaping on one pole on a cart) may run without the catch taking over; then, where
        the supervisor has a planner (:func:`supervisor_for` gives it one), the brake and the planner for the rest of
        the run, after every knock too (a ``law_failed`` decision): a law that cannot reach the catch with the motor
        it has (a heavy pole on a light cart at the default force bound pumps the pole to within a few tenths of a
        radian of upright and back, for ever) hands over to a plan, which finds the swing-up within the bound.
        ``inf``: the law until the catch.
    mpc_step_budget : float or None
        s of wall time one control step of the swing-up MPC may take (its DDP iteration): a step over it applies the
        previous solution's input shifted to this step instead of its own late answer (the ``step_budget`` of
        :class:`~cartpole.mpc.ddp_mpc.DDPMPCController`; counted in :meth:`Supervisor.summary`'s ``mpc_ms``:
        ``over_budget``). The solve runs to its end; what is bounded is that no ctrl waits for an answer later than
        the budget. None (default): every step applies its own answer (a run that does not depend on the machine's
        speed; a live run paced in real time would set the control period).
    catch_rollout : float or None
        s of the catch run on the planning model's exact step (its ctrl held over the control period) that certify a
        catch from a state outside its verified basin but within ``release_factor * rho``: when that run enters the
        basin (``e' S e < rho``) within this time, every state finite and every joint inside its range, the catch
        takes the state (a ``catch`` decision with ``certified_s``, the time the run took to the basin). For episodes
        that end when a pole falls (Gymnasium's), where a state the catch holds must not be braked or planned from.
        None (default): the verified basin alone.
    mpc_horizon : float or None
        s the swing-up MPC looks ahead (``MPCOptions.horizon``, rounded to whole control periods), or None (default):
        :data:`MPC_HORIZON`.
    mpc_iterations : int
        DDP iterations the swing-up MPC takes each control period (``MPCOptions.iterations``, 1 to
        :data:`~cartpole.mpc.options.MAX_ITERATIONS`; default 1, the real-time iteration).
    mpc_converge : bool
        At each take-over, first converge the swing-up MPC's solution
        (:meth:`~cartpole.mpc.ddp_mpc.DDPMPCController.converge`, as the MPC designed from a start converges its first
        solution offline) from the state predicted ``mpc_latency`` s ahead under the brake, its wall time charged as
        latency: the brake acts meanwhile (as while a plan is made) and the MPC from the later of the predicted time and
        the solve's end (``charged_latency`` instead of both, when set); the ``mpc`` decision keeps the solve's wall
        time, what was charged and its iterations (True). False (default): the MPC acts at once, its solution the
        upright's inputs improved one iteration a period in the loop.
    mpc_latency : float
        s of wall time predicted for that solve (``mpc_converge``): the state it starts from is predicted this far
        ahead, and the MPC never acts before it (a solve that takes longer is charged its wall time; default
        :data:`MPC_CONVERGE_LATENCY`).
    plan_in_worker : bool or None
        Make each plan in a child process (:class:`cartpole.supervise.worker.PlanWorker`: forked at the first plan
        and kept between plans) that is killed once a plan has run ``plan_budget`` s of wall time (the next plan
        forks a new one): planning from any state is then bounded by the budget (a ``plan_timeout`` decision, then
        ``plan_failed``), where in the caller's thread (False) the budget is checked only after the planner returns.
        The run waits for the child (unless ``plan_while_running``), and its wall time is charged as in the caller's
        thread; the same plans, the same run. None (default): True in the supervisor :func:`supervisor_for` makes
        (what every command runs) where the platform can fork (Linux, macOS), else False (Windows); False for a
        :class:`Supervisor` built with a planner of your own (its plans need not pickle, its side effects stay in
        this process) unless ``plan_while_running``. Call :meth:`Supervisor.close` (or use it in a ``with`` block)
        when the run ends.
    plan_while_running : bool
        With a worker (``plan_in_worker`` not False): the run goes on while the worker plans (the brake acting),
        polled at each call, the plan used from the simulated time it comes in (charged that time since it was
        asked for, at least ``charged_latency``), killed once over ``plan_budget``; so are re-plans while tracking
        (``replan_every``), the old plan tracked meanwhile. For a run paced in real time (a live view: :func:`cartpole.apps.live.paced_supervisor` turns it on),
        where simulated time is wall time; a run stepped as fast as possible would charge whatever simulated time it
        stepped meanwhile, which depends on the machine's speed: not reproducible. False (default): the run waits for
        the plan and charges its measured wall time (or ``charged_latency``: reproducible on any machine).
    warm_worker : bool
        With a worker: before the first fork, make one plan in this process (:meth:`Supervisor.prepare`, from the
        model's hanging state, the plan discarded), so that what the planner builds (CasADi solvers and functions,
        the compiled C of :mod:`cartpole.codegen` loaded) is in every child from its start, copy-on-write: a child
        forked after a kill starts warm, and a model whose first (cold) plan takes longer than ``plan_budget`` still
        plans (True, default; ``docs/recovery.md`` gives the cold and warm times); its wall time is
        :attr:`Supervisor.prepare_s`. False: every child starts as cold as this process.
    cart_plans : bool
        On one pole driven by the cart (where the energy law swings up on its own): plan each swing-up too, warm from
        the library's plans, following the library's plan from hanging while the plan is made from a start near it
        (:class:`~cartpole.supervise.lead_in.PlanLeadIn`, which predicts the state the plan starts from), else the
        energy law, and tracking each plan to its end before the catch takes over (True; :func:`supervisor_for` does
        so only when its library holds a plan; a sparse dm_control task's plans by
        :func:`~cartpole.planning.box_tail.box_tail_planner`), or the energy law and the catch alone (False,
        default). The law pumps longer than a planned swing-up (``docs/dmc.md``); a plan that fails leaves the lead-in
        or the law in charge.
    """

    plan_budget: float = 30.0
    latency: float = 0.5
    calm_rate: float = 6.0
    funnel: float = 0.6
    release_factor: float = 20.0
    retry_after: float = 0.5
    brake_time: float = 0.15
    calm_budget: float = 10.0
    charged_latency: float | None = None
    exact_plans: bool = True
    replan_every: float | None = None
    calm_brake_time: float | None = None
    calm_energy: float | None = None
    warm_tails: bool = False
    calm_drain: bool = False
    swingup_mpc: bool = False
    mpc_energy: float = HINGE_MPC_ENERGY
    mpc_floor: float | None = HINGE_MPC_FLOOR
    mpc_budget: float = 10.0
    law_budget: float = 20.0
    mpc_step_budget: float | None = None
    mpc_horizon: float | None = None
    mpc_iterations: int = 1
    catch_rollout: float | None = None
    mpc_converge: bool = False
    mpc_latency: float = MPC_CONVERGE_LATENCY
    plan_in_worker: bool | None = None
    plan_while_running: bool = False
    warm_worker: bool = True
    cart_plans: bool = False

    error: ClassVar[type] = SupervisorError
    SCALARS: ClassVar[tuple] = ("plan_budget", "latency", "calm_rate", "funnel", "release_factor", "retry_after",
                                "brake_time", "calm_budget", "charged_latency", "mpc_energy", "mpc_budget",
                                "law_budget", "mpc_step_budget", "mpc_floor", "mpc_latency", "mpc_horizon",
                                "mpc_iterations", "catch_rollout")

    def __post_init__(self):
        for name, unit in (("plan_budget", "s"), ("latency", "s"), ("calm_rate", "rad/s"), ("funnel", "rad"),
                           ("retry_after", "s"), ("brake_time", "s"), ("calm_budget", "s"), ("mpc_energy", "J"),
                           ("mpc_budget", "s"), ("mpc_latency", "s"), ("law_budget", "s")):
            self.number(name, low=0.0, low_open=True, unit=unit)
        self.number("release_factor", low=1.0, low_open=True, unit="(ratio)")
        self.number("charged_latency", low=0.0, unit="s", optional=True)
        self.number("replan_every", low=0.0, low_open=True, unit="s", optional=True)
        self.number("calm_energy", unit="J", optional=True)
        self.number("calm_brake_time", low=0.0, low_open=True, unit="s", optional=True)
        self.number("mpc_step_budget", low=0.0, low_open=True, unit="s", optional=True)
        self.number("mpc_floor", low=0.0, unit="J", optional=True)
        self.number("mpc_horizon", low=0.0, low_open=True, unit="s", optional=True)
        self.number("catch_rollout", low=0.0, low_open=True, unit="s", optional=True)
        self.number("mpc_iterations", low=1, high=MAX_ITERATIONS, integer=True)
        for name in ("exact_plans", "warm_tails", "calm_drain", "swingup_mpc", "plan_while_running", "warm_worker",
                     "cart_plans", "mpc_converge"):
            if not isinstance(getattr(self, name), bool):
                raise SupervisorError(f"{name} = {getattr(self, name)!r} must be True or False.")
        if self.plan_in_worker is not None and not isinstance(self.plan_in_worker, bool):
            raise SupervisorError(f"plan_in_worker = {self.plan_in_worker!r} must be True, False or None (a worker "
                                  "where the platform can fork).")
        if self.in_worker and not fork_available():
            raise SupervisorError("plan_in_worker and plan_while_running need a platform that can fork (Linux, macOS); "
                                  "leave them False here.")
        if self.plan_while_running and self.plan_in_worker is False:
            raise SupervisorError("plan_while_running needs plan_in_worker=True: only a plan made in a worker "
                                  "process lets the run go on meanwhile.")

    @property
    def in_worker(self) -> bool:
        """Whether plans are made in a worker process: ``plan_in_worker``, or when None ``plan_while_running``
        (:func:`supervisor_for` resolves None to whether the platform can fork)."""
        return bool(self.plan_in_worker) or (self.plan_in_worker is None and self.plan_while_running)


@dataclass(frozen=True)
class Decision:
    """One decision of the supervisor.

    Attributes
    ----------
    t : float
        s, simulated time of the decision.
    kind : str
        ``"catch"``, ``"swingup"`` (the swing-up law took over), ``"brake"``, ``"plan"`` (a plan requested),
        ``"track"`` (a plan ready and tracked), ``"plan_failed"``, ``"lost"`` (left the tracking funnel),
        ``"calm_timeout"`` (the brake did not calm the state within ``calm_budget``: planned from it as it is),
        ``"stalled"`` (the swing-up law has left every hinge at rest outside the basin for :data:`STALL_SECONDS`),
        ``"law_failed"`` (the swing-up law ran ``law_budget`` s without a catch: the brake and the planner from then
        on),
        ``"plan_timeout"`` (a plan made in a worker stopped at ``plan_budget``; ``plan_failed`` follows),
        ``"plan_dropped"`` (with ``plan_while_running``, the catch took over before the plan came: not waited for;
        with ``replan``, a re-plan still on its way when the plan it was for was over);
        ``"mpc"`` (the swing-up MPC took over), ``"mpc_failed"`` (it ran ``mpc_budget`` s without a catch, or the energy
        rose above its band).
    detail : dict
        What the decision rests on (cost, rates, planning wall time, the failure's sentence...).
    """

    t: float
    kind: str
    detail: dict = dataclasses.field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready ``{"t", "kind", **detail}``."""
        return {"t": self.t, "kind": self.kind, **self.detail}


class PassiveBrake:
    """``u = u* - kp (q_j - q*_j) - kd q_dot_j`` through each actuator's driven joint ``j``: a passive spring and
    damper on the actuated joints, so the total energy (with the spring's) never grows, whatever the state.

    Parameters
    ----------
    model : CartPoleModel
        Its ``params.actuated`` (the joint each actuator drives), ``gears``, ``x_eq``, ``u_eq``.
    inertia : (nv,) array
        Joint-space inertia diagonal at upright (kg or kg m^2).
    time_constant : float
        s; ``kd = inertia / time_constant``, ``kp = inertia / time_constant^2`` in N/m, N m/rad (divided by the gear
        for ctrl units).
    u_limits : (nu, 2) array
        ctrl clip.
    """

    def __init__(self, model: CartPoleModel, inertia, time_constant: float, u_limits):
        self.model = model
        self.joints = tuple(int(j) for j in model.params.actuated)
        gears = np.asarray(model.params.gears, dtype=float).ravel()
        inertia = np.asarray(inertia, dtype=float)
        self.kd = np.array([inertia[j] / time_constant / g for j, g in zip(self.joints, gears)])
        self.kp = np.array([inertia[j] / time_constant ** 2 / g for j, g in zip(self.joints, gears)])
        self.u_limits = np.asarray(u_limits, dtype=float).reshape(-1, 2)
        self.nq = model.nq

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at state ``x`` (nx,)."""
        x = np.asarray(x, dtype=float)
        x_eq = np.asarray(self.model.x_eq, dtype=float)
        j = list(self.joints)
        dq = x[j] - x_eq[j]
        hinge = np.isin(j, self.model.hinges)
        dq = np.where(hinge, wrap_angle(dq), dq)
        u = np.asarray(self.model.u_eq, dtype=float).ravel() - self.kp * dq - self.kd * x[[self.nq + i for i in j]]
        return np.clip(u, self.u_limits[:, 0], self.u_limits[:, 1])


class Supervisor:
    """Recover from any state for as long as it runs: catch, swing-up law, brake, plan and track (module docstring).

    Parameters
    ----------
    model : CartPoleModel
        The planning model (its ``x_eq``, hinges, exact discrete step for the prediction).
    catch : LinearFeedback
        The balancing LQR, with ``S``.
    rho : float
        The catch's verified basin level (``e' S e < rho``; e.g. ``BasinEstimate.rho``).
    brake : callable
        ``(t, x) -> ctrl``: the energy-removing law (:class:`PassiveBrake`).
    planner : callable, optional
        ``planner(x0 (nx,)) -> SwingupPlan`` (e.g. :func:`cartpole.planning.trajopt.trajopt_swingup` bound to the
        model); raises :class:`~cartpole.errors.CartPoleError` when it finds none. None: never plans.
    swingup : callable, optional
        ``(t, x) -> ctrl``, a law that swings up from any state on its own (the energy law on one pole); when given
        it runs outside the basin instead of braking and planning.
    options : SupervisorOptions, optional
    basin : BasinEstimate, optional
        The estimate ``rho`` came from, kept for the run's report.
    library : PlanLibrary, optional
        Warm starts for the planner (:mod:`cartpole.planning.library`): each plan is asked for with the stored plan
        nearest the predicted start by the catch's cost-to-go metric ``S`` (``planner(x0, guess=...)``), and every
        plan the supervisor makes is added to it, a warm start for the next knockdown.
    calm_brake : callable, optional
        ``(t, x) -> ctrl``, the brake while the state is fast (default ``brake``, which acts while a plan is on its
        way and after a failed one).

    Attributes
    ----------
    mpc : callable or None
        ``(t, x) -> ctrl``, the swing-up MPC (``swingup_mpc``: :class:`~cartpole.mpc.ddp_mpc.DDPMPCController`, set by
        :func:`supervisor_for`), called with the time since it took over (reset at each take-over when it has
        ``reset()``); None (the default): never.
    period : float or None
        s, the control period the supervisor is called at (its ctrl held over it), as :func:`supervisor_for` sets it;
        None: every physics step. Used where the supervisor predicts its catch's run (``catch_rollout``).
    mpc_design : callable or None
        ``mpc_design(x (nx,)) -> (t, x) -> ctrl``: designs the swing-up MPC afresh from the state it takes over (e.g.
        :func:`cartpole.apps.envscore.best_mpc`'s closed-loop choice among horizons), replacing :attr:`mpc` at each
        take-over. As with ``mpc_converge``, the design starts from the state predicted ``mpc_latency`` s (or
        ``charged_latency``) ahead under the brake, its wall time is charged (the brake acting meanwhile) and the
        ``mpc`` decision keeps it (``design_s``, ``charged_s``, and a chosen design's ``choice`` and
        ``predicted_return``); with ``charged_latency=0`` (an environment that waits for each action, as dm_control's
        episodes do) from the take-over state itself. A design that raises :class:`~cartpole.errors.CartPoleError`
        leaves the previous MPC (its ``status`` in the decision). None (default): :attr:`mpc` as it is.
    decisions : list of Decision
    mode : str
        ``"catch"``, ``"swingup"``, ``"brake"``, ``"wait"`` (a plan on its way), ``"track"`` or ``"mpc"``.
    plan_seconds : list of float
        Wall time of every plan, s.
    """

    def __init__(self, model: CartPoleModel, catch: LinearFeedback, rho: float, brake: Callable, *,
                 planner: Callable | None = None, swingup: Callable | None = None,
                 options: SupervisorOptions | None = None, basin=None, library=None,
                 calm_brake: Callable | None = None):
        if catch.S is None:
            raise SupervisorError("The supervisor's catch needs its cost-to-go S to test the basin; build it with "
                                  "LinearFeedback.for_model.")
        self.model, self.catch, self.rho, self.brake = model, catch, float(rho), brake
        self.calm_brake = brake if calm_brake is None else calm_brake
        self.planner, self.swingup = planner, swingup
        self.options = SupervisorOptions() if options is None else options
        self.hinges = tuple(model.hinges)
        self.basin = basin
        self.library = library
        self.prepare_s = None  # s the planner's warm-up in this process took (prepare), None before it
        self.mpc = None
        self.mpc_design = None
        self.period = None
        self.reset()

    def reset(self) -> None:
        """Forget the run: no plan, no decisions."""
        self.mode = "start"
        self.decisions: list[Decision] = []
        self.plan_seconds: list[float] = []
        self.plan = None
        self.plan_t0 = 0.0
        self.ready_at = np.inf
        self.retry_at = -np.inf
        self.plans = 0
        self.failures = 0
        self.warm_plans = 0
        self.fast_since = None
        self.pending = None  # a re-plan made while tracking: (plan, t0, ready_at)
        self.replan_at = np.inf
        self.still_since, self.stalled = None, False  # the swing-up law's stall watch (STALL_SECONDS)
        self.law_t0, self.law_spent = None, False  # when the swing-up law took over; whether it ran out (law_budget)
        self.mpc_t0, self.mpc_spent = None, False  # when the MPC took over; whether it failed since a catch or knock
        self.mpc_ready = -np.inf  # when the MPC acts (mpc_converge: the brake until its solve is charged)
        self.mpc_converge_s: list[float] = []  # wall time of each take-over's solve (mpc_converge), s
        self.mpc_ms: list[float] = []  # the swing-up MPC's wall time per step (ms), its earlier take-overs
        self.mpc_over = 0  # steps of its earlier take-overs over mpc_step_budget
        if getattr(self, "server", None) is not None:
            self.close()
        self.server = self.asked = self.replan_asked = None  # the planning worker (plan_in_worker); what a plan on its way was asked

    @property
    def latency(self) -> float:
        """s, the planning latency the next plan is predicted with: 1.25 times the median measured so far (a plan
        that comes late is tracked from where its clock has got to, so erring long is cheaper), else the option;
        ``charged_latency`` when set."""
        if self.options.charged_latency is not None:
            return float(self.options.charged_latency)
        return 1.25 * float(np.median(self.plan_seconds)) if self.plan_seconds else self.options.latency

    def _decide(self, t: float, kind: str, **detail) -> None:
        self.decisions.append(Decision(float(t), kind, detail))

    def _set(self, t: float, mode: str, **detail) -> None:
        if mode != self.mode:
            self.mode = mode
            self._decide(t, mode, **detail)

    def _fast(self, x) -> bool:
        """Any hinge faster than ``calm_rate``, or the energy above ``calm_energy`` when set."""
        rates = np.abs(np.asarray(x, dtype=float)[[self.model.nq + h for h in self.hinges]])
        if np.any(rates > self.options.calm_rate):
            return True
        return self.options.calm_energy is not None and self._energy(x) > self.options.calm_energy

    def _catch_certified(self, t: float, x) -> float | None:
        """With ``catch_rollout``: s the catch, run from ``x`` (nx,) on the planning model's exact step with its ctrl
        held over :attr:`period`, takes to bring the state into its verified basin, every state finite and every
        joint inside its range; None when it does not within ``catch_rollout`` s (or without the option)."""
        horizon = self.options.catch_rollout
        if horizon is None:
            return None
        dt = float(self.model.dt)
        hold = steps_per_period(self.period, dt)
        ranges = self.model.params.joint_ranges
        x = np.asarray(x, dtype=float)
        for k in range(int(np.ceil(horizon / (hold * dt) - 1e-9))):
            u = self.catch(t + k * hold * dt, x)
            for _ in range(hold):
                x = self.model.step_np(x, u)
            q = x[:self.model.nq]
            if not np.all(np.isfinite(x)) or np.any(q < ranges[:, 0]) or np.any(q > ranges[:, 1]):
                return None
            if float(self.catch.cost_to_go(x)) < self.rho:
                return (k + 1) * hold * dt
        return None

    def _energy(self, x) -> float:
        """J, the model's total mechanical energy at ``x`` (zero at upright rest)."""
        return float(self.model.energy(np.asarray(x, dtype=float)))

    def _lost(self, t: float, x) -> bool:
        tau = min(t - self.plan_t0, self.plan.trajectory.duration)
        ref = self.plan.trajectory.state(tau)
        err = wrap_angle(np.asarray(x, dtype=float)[list(self.hinges)] - np.asarray(ref)[list(self.hinges)])
        return bool(np.max(np.abs(err)) > self.options.funnel)

    def _at_start(self, x) -> bool:
        """Whether ``x`` is still at the plan's start: every hinge within ``funnel / 2`` rad and
        :data:`RESTART_RATE` rad/s of it (a plan later than predicted then starts from its beginning)."""
        x = np.asarray(x, dtype=float)
        ref = np.asarray(self.plan.trajectory.state(float(self.plan.trajectory.t[0])), dtype=float)
        h = list(self.hinges)
        hv = [self.model.nq + i for i in h]
        return bool(np.max(np.abs(wrap_angle(x[h] - ref[h]))) <= 0.5 * self.options.funnel
                    and np.max(np.abs(x[hv] - ref[hv])) <= RESTART_RATE)

    def _watch_stall(self, t: float, x) -> None:
        """Log a ``stalled`` decision once per fall when the swing-up law has held every hinge at rest for
        :data:`STALL_SECONDS`, naming a hinge that rests on its range limit."""
        rates = np.abs(x[[self.model.nq + h for h in self.hinges]])
        if self.stalled or np.any(rates > STALL_RATE):
            self.still_since = None
            return
        self.still_since = t if self.still_since is None else self.still_since
        if t - self.still_since < STALL_SECONDS - 1e-9:
            return
        self.stalled = True
        why = (f"the swing-up law has held every pole at rest outside the catch's basin for {STALL_SECONDS:g} s, so it "
               f"will not swing up from here")
        for h in self.hinges:
            joint = self.model.params.joints[h]
            lo, hi = (float(v) for v in joint.range)
            if min(x[h] - lo, hi - x[h]) < STALL_LIMIT_TOL:
                off = float(np.degrees(wrap_angle(x[h] - float(np.asarray(self.model.x_eq)[h]))))
                why = (f"hinge '{joint.name}' rests on its range limit [{lo:.4g}, {hi:.4g}] rad, {off:.1f} deg from "
                       f"upright, where the swing-up law cannot lift it (a range that keeps the pole from hanging "
                       f"down: widen it, or limited=\"false\", for a pole that can swing through)")
        self._decide(t, "stalled", x0=[float(v) for v in x], reason=why)

    def _request_plan(self, t: float, x) -> None:
        """Plan from the state predicted ``latency`` s ahead under the brake; the plan is used from ``t + W``."""
        self._drop_replan(t)
        lat = self.latency
        self.pending = None
        steps = max(1, int(round(lat / self.model.dt)))
        xs, _ = model_rollout(self.model, self.brake, x, steps, t0=t)
        x_pred = xs[-1]
        if self.options.in_worker:
            self._worker()  # made (the planner warmed here first: prepare_s) before the plan's clock starts
        self.plans += 1
        start = time.perf_counter()
        ask = _Ask(t, x_pred, steps, lat, None)
        try:
            if not np.all(np.isfinite(x_pred)):
                raise CartPoleError("the prediction over the planning latency is not finite")
            request, dist = self._plan_request(x_pred)
            ask = ask._replace(dist=dist)
            if self.options.plan_while_running:  # the run goes on; __call__ polls the worker
                self._worker().submit(request)
                self.asked, self.mode, self.ready_at = ask, "wait", np.inf
                return
            plan = self._call_planner(t, request)
        except CartPoleError as exc:
            plan, why = None, str(exc)
        wall = time.perf_counter() - start
        charged = wall if self.options.charged_latency is None else float(self.options.charged_latency)
        self._take_plan(ask, plan, wall, charged, None if plan is not None else why)

    def _plan_request(self, x_pred):
        """``(request, distance)``: the planning call from ``x_pred`` (warm-started from the library as the options
        say) as a picklable request for :meth:`_serve`, and the library's distance to its warm start (None without
        one)."""
        if self.library is not None and len(self.library) and self.options.warm_tails:
            cart = self.options.cart_plans  # the state itself: a cart's energy is mostly the cart's
            guesses = self.library.knot_guesses(self.model, x_pred, count=WARM_TRIES,
                                                energy_weight=0.0 if cart else KNOT_ENERGY_WEIGHT,
                                                min_tail=0.0 if cart else KNOT_MIN_TAIL)
            return ("_plan_warm", (x_pred, guesses), {}), guesses[0][1]
        if self.library is not None and len(self.library):
            guess = self.library.guess_for(self.model, x_pred, metric=self.catch.S)
            dist = self.library.nearest(x_pred, metric=self.catch.S)[1]
            return ("planner", (x_pred,), {} if guess is None else {"guess": guess}), dist
        return ("planner", (x_pred,), {}), None

    def _serve(self, request):
        """A plan for ``request``, ``(name, args, kwargs)``: ``self.planner`` or :meth:`_plan_warm` called with them
        (in the caller's thread, or in the worker process's copy of this supervisor)."""
        name, args, kwargs = request
        return (self.planner if name == "planner" else self._plan_warm)(*args, **kwargs)

    def _worker(self) -> PlanWorker:
        """The planning worker process (:class:`~cartpole.supervise.worker.PlanWorker`), made at first use: kept
        between plans, so what one plan built in it (its solvers) serves the next."""
        if self.server is None:
            if self.options.warm_worker and self.prepare_s is None:
                self.prepare()  # before the first fork: every child starts with what this plan built
            self.server = PlanWorker(self._serve)
        return self.server

    #: Whether the last :meth:`prepare` was stopped at ``plan_budget`` before its plan ended.
    prepare_timed_out: bool = False

    def prepare(self, x0=None, *, again: bool = False) -> float:
        """Make one plan in this process and discard it, so that what the planner builds (CasADi solvers and
        functions, the compiled C of :mod:`cartpole.codegen` loaded, the model's derived functions) is here before
        a worker is forked: every child then has it from its start (copy-on-write), a child forked after a kill too.
        ``warm_worker`` does this before the first fork; a live run calls it before it starts, so that its loop never
        waits for it. The plan is asked for as the supervisor asks (its library's warm start), from ``x0`` (nx,)
        (default the model's hanging state); it is neither used nor added to the library, and one that fails (a
        :class:`~cartpole.errors.CartPoleError`) has built its solvers all the same. It is bounded by ``plan_budget``
        (s of wall time, as a plan in a worker; :func:`~cartpole.supervise.worker.run_within`: stopped at its first
        Python step past the budget, in the main thread): one stopped there sets :attr:`prepare_timed_out` and logs a
        warning (what it built before is kept, and the model counts as prepared: the next supervisor of it does not
        spend another budget); the workers then start as warm as it got.

        Parameters
        ----------
        x0 : (nx,) array, optional
            The state planned from.
        again : bool
            Plan even when a supervisor of this model (and kind of plan) has prepared its planner in this process
            already (default False: then nothing is done, its solvers are here).

        Returns
        -------
        float
            s of wall time it took (also :attr:`prepare_s`; 0 without a planner, or when done already; about
            ``plan_budget`` when it was stopped there: :attr:`prepare_timed_out`).
        """
        start = time.perf_counter()
        ready = self.planner is None or (self._prepare_key() in _PREPARED and not again)
        if not ready:
            x = np.asarray(self.model.x_hanging if x0 is None else x0, dtype=float)

            def warm_up() -> None:
                try:
                    request, _ = self._plan_request(x)
                    self._serve(request)
                except CartPoleError:
                    pass

            self.prepare_timed_out = not run_within(warm_up, self.options.plan_budget)
            if self.prepare_timed_out:
                _LOG.warning("The planner's warm-up plan was stopped at the plan budget of %g s (plan_budget); "
                             "the planning workers start from what it built by then.", self.options.plan_budget)
            _PREPARED.add(self._prepare_key())
        self.prepare_s = 0.0 if ready else time.perf_counter() - start
        return self.prepare_s

    def _prepare_key(self) -> tuple:
        """What :data:`_PREPARED` knows a prepared planner by: the model's hash and the kind of plan."""
        return model_key(self.model), self.options.exact_plans, self.options.warm_tails

    def __enter__(self) -> "Supervisor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _take_plan(self, ask, plan, wall: float, charged: float, why: str | None) -> None:
        """Use ``plan`` asked for by ``ask`` (:class:`_Ask`) that took ``wall`` s and is charged ``charged`` s of
        simulated time, or log its failure (``plan`` None, ``why``) and brake until a retry."""
        t, x_pred, steps, lat, dist = ask
        self.plan_seconds.append(wall)
        if plan is not None and wall > self.options.plan_budget:
            plan, why = None, f"the plan took {wall:.1f} s, over the budget of {self.options.plan_budget:g} s"
        if plan is None:
            self.failures += 1
            self.retry_at = t + charged + self.options.retry_after
            self._decide(t, "plan_failed", wall_s=wall, charged_s=charged, reason=why,
                         x0=[float(v) for v in np.asarray(x_pred, dtype=float)],
                         **({} if dist is None else {"library_distance": dist}))
            self.mode = None  # the fallback that acts next is logged as its own decision (brake, mpc, plan)
            return
        # used from the later of its arrival and the time it was planned to start from (an early plan waits)
        self.plan, self.plan_t0 = plan, t + steps * self.model.dt
        self.ready_at = max(t + charged, self.plan_t0)
        warm = _warm(plan)
        self.warm_plans += int(warm)
        if self.library is not None:
            self.library = self.library.with_plan(x_pred, plan.trajectory, wall)
        self._decide(t, "plan", wall_s=wall, charged_s=charged, predicted_latency_s=lat, T=float(plan.trajectory.duration), warm=warm,
                     **({} if dist is None else {"library_distance": dist}))
        self.mode = "wait"

    def _poll_worker(self, t: float) -> None:
        """With ``plan_while_running``: take the worker's plan once it is in (charged the simulated time since it was
        asked for), kill it once over ``plan_budget`` (a failed plan), or drop it when the state no longer waits for
        it (the catch took over meanwhile)."""
        worker, ask = self.server, self.asked
        if self.mode != "wait":
            self.close()
            self._decide(t, "plan_dropped", wall_s=worker.elapsed, asked_at=ask.t)
            return
        answer = self._worker_answer()
        if answer is None:
            return
        plan, why, wall, timed_out = answer
        if timed_out:
            self._decide(ask.t, "plan_timeout", wall_s=wall, budget_s=self.options.plan_budget)
        self.asked = None
        charged = max(t - ask.t, self.options.charged_latency or 0.0)
        self._take_plan(ask, plan, wall, charged, why)

    def _worker_answer(self):
        """The planning worker's answer, polled: ``(plan, why, wall, timed_out)`` once the plan is in (``why`` the
        failure's sentence, ``plan`` None on failure) or the worker was killed for running over ``plan_budget``
        (``timed_out``; ``wall`` its wall time, s); None while it still plans within the budget."""
        worker = self.server
        budget, wall = self.options.plan_budget, worker.elapsed
        if worker.poll():
            try:
                return worker.result(), None, wall, False
            except CartPoleError as exc:
                return None, str(exc), wall, False
        if wall > budget:
            worker.kill()
            return None, timeout_sentence(wall, budget), wall, True
        return None

    def close(self) -> None:
        """End the planning worker process (``plan_in_worker``), a plan still on its way in it dropped: call it when
        the run ends (an idle worker otherwise waits for the next plan until this process exits)."""
        if self.server is not None:
            self.server.close()
        self.server = self.asked = self.replan_asked = None

    def _call_planner(self, t: float, request):
        """The plan for ``request`` (:meth:`_serve`) in the caller's thread, or with ``plan_in_worker`` in the worker
        process, killed at ``plan_budget`` (a ``plan_timeout`` decision, then
        :class:`~cartpole.supervise.worker.PlanTimeout`)."""
        if not self.options.in_worker:
            return self._serve(request)
        budget = self.options.plan_budget
        return self._worker().wait(request, budget, on_timeout=lambda wall: self._decide(t, "plan_timeout",
                                                                                         wall_s=wall, budget_s=budget))

    def _plan_warm(self, x0, guesses):
        """The planner from ``x0`` warm-started from each of ``guesses`` (``(Trajectory, distance)``, the nearest
        knots' tails: :meth:`~cartpole.planning.library.PlanLibrary.knot_guesses`) in turn, never cold
        (``planner(x0, guess=..., cold=False)``): the first plan that converges. Raises the last failure's
        :class:`~cartpole.errors.CartPoleError` when none does (the supervisor brakes and tries again from the next
        predicted state)."""
        failure = None
        for guess, _ in guesses:
            try:
                return self.planner(x0, guess=guess, cold=False)
            except CartPoleError as exc:
                failure = exc
        raise failure

    def _receding(self, t: float, x) -> None:
        """While tracking: take the re-plan made earlier once it is ready, else make one when it is due
        (``replan_every``) and the plan has more than that and the latency left."""
        if self.pending is not None and t >= self.pending[2] - 1e-12:
            self.plan, self.plan_t0 = self.pending[0], self.pending[1]
            self.pending = None
            self._decide(t, "track", replanned=True, late_s=max(0.0, t - self.plan_t0))
            return
        left = self.plan.trajectory.duration - (t - self.plan_t0)
        if self.replan_asked is not None:
            self._poll_replan(t)
        elif self.pending is None and t >= self.replan_at and left > self.options.replan_every + self.latency:
            self._request_replan(t, x)

    def _poll_replan(self, t: float) -> None:
        """With ``plan_while_running``, while tracking: take the worker's re-plan once it is in (charged the simulated
        time since it was asked for), or kill it once over ``plan_budget`` (``replan_failed``)."""
        ask, answer = self.replan_asked, self._worker_answer()
        if answer is None:
            return
        new, why, wall, _ = answer
        self.replan_asked = None
        self._take_replan(ask, new, wall, max(t - ask.t, self.options.charged_latency or 0.0), why)

    def _drop_replan(self, t: float) -> None:
        """A re-plan still on its way when the plan it was for is over (lost, caught, knocked): its worker killed
        (``plan_dropped``, ``replan``), the next plan forks a new one."""
        if self.replan_asked is not None:
            self._decide(t, "plan_dropped", wall_s=self.server.elapsed, asked_at=self.replan_asked.t, replan=True)
            self.server.kill()
            self.replan_asked = None

    def _request_replan(self, t: float, x) -> None:
        """A plan from the state predicted ``latency`` s ahead under the tracked plan's TVLQR, warm-started from the
        rest of that plan (:func:`~cartpole.planning.library.trajectory_tail`); used from ``t + W``, the tracked plan
        meanwhile."""
        lat = self.latency
        steps = max(1, int(round(lat / self.model.dt)))
        plan, t_plan = self.plan, self.plan_t0
        xs, _ = model_rollout(self.model, lambda tt, xx: plan.controller(tt - t_plan, xx), x, steps, t0=t,
                              u_limits=self.catch.u_limits)
        x_pred, t0 = xs[-1], t + steps * self.model.dt
        self.replan_at = t + self.options.replan_every
        self.plans += 1
        start = time.perf_counter()
        ask = _Ask(t, x_pred, steps, lat, None)
        try:
            if not np.all(np.isfinite(x_pred)):
                raise CartPoleError("the prediction over the planning latency is not finite")
            warm_only = {"cold": False} if self.options.warm_tails else {}  # a failed re-plan keeps the old plan
            tail = trajectory_tail(plan.trajectory, t0 - t_plan)
            request = ("planner", (x_pred,), {"guess": tail, **warm_only})
            if self.options.plan_while_running:  # the run goes on, the old plan tracked; _receding polls
                self._worker().submit(request)
                self.replan_asked = ask
                return
            new = self._call_planner(t, request)
            why = None
        except CartPoleError as exc:
            new, why = None, str(exc)
        wall = time.perf_counter() - start
        charged = wall if self.options.charged_latency is None else float(self.options.charged_latency)
        self._take_replan(ask, new, wall, charged, why)

    def _take_replan(self, ask, new, wall: float, charged: float, why: str | None) -> None:
        """Keep the re-plan ``new`` asked for by ``ask`` (:class:`_Ask`), which took ``wall`` s and is charged
        ``charged`` s, to be tracked from when it is ready (``pending``), or log its failure (``new`` None, ``why``)
        and keep the plan being tracked."""
        t, x_pred, steps, lat, _ = ask
        t0 = t + steps * self.model.dt
        self.plan_seconds.append(wall)
        if new is not None and wall > self.options.plan_budget:
            new, why = None, f"the plan took {wall:.1f} s, over the budget of {self.options.plan_budget:g} s"
        if new is None:
            self.failures += 1
            self._decide(t, "replan_failed", wall_s=wall, charged_s=charged, reason=why)
            return
        warm = _warm(new)
        self.warm_plans += int(warm)
        if self.library is not None:
            self.library = self.library.with_plan(x_pred, new.trajectory, wall)
        self.pending = (new, t0, max(t + charged, t0))
        self._decide(t, "replan", wall_s=wall, charged_s=charged, predicted_latency_s=lat,
                     T=float(new.trajectory.duration), warm=warm)

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (nu,) at time ``t`` (s) for state ``x`` (nx,)."""
        t = float(t)
        x = np.asarray(x, dtype=float)
        cost = float(self.catch.cost_to_go(x))
        certified = None
        if self.mode != "catch" and self.rho <= cost < self.options.release_factor * self.rho:
            certified = self._catch_certified(t, x)
        if (cost < self.rho or certified is not None
                or (self.mode == "catch" and cost < self.options.release_factor * self.rho)) \
                and not self._plan_holds(t, x):
            self._set(t, "catch", cost=cost, **({} if certified is None else {"certified_s": certified}))
            self.still_since, self.stalled, self.mpc_spent = None, False, False
            self.law_t0 = None  # a law that ran out once stays out (law_budget): the motor is what it is
            return self.catch(t, x)
        if self.swingup is not None and not self._law_done(t, cost):
            self._set(t, "swingup", cost=cost)
            self._watch_stall(t, x)
            return self.swingup(t, x)
        if self.asked is not None:
            self._poll_worker(t)
        if self.mode == "mpc" and not self._mpc_done(t, x, cost):
            return self._mpc_or_brake(t, x)
        if self.mode == "wait" and t >= self.ready_at - 1e-12:
            late = max(0.0, t - self.plan_t0)
            restart = late > 0.5 * self.model.dt and self._at_start(x)
            if restart:  # still where the plan starts (the brake holds a calm state): the plan from its start
                self.plan_t0 = t
            self._set(t, "track", late_s=late, restarted=restart)
            self.replan_at = t + (np.inf if self.options.replan_every is None else self.options.replan_every)
        if self.mode == "track":
            over = t - self.plan_t0 >= self.plan.trajectory.duration
            if over and cost < self.options.release_factor * self.rho:  # the plan's end: the catch takes it
                self._set(t, "catch", cost=cost)
                return self.catch(t, x)
            if not over and not self._lost(t, x):
                self._receding(t, x)
                return self.plan.controller(t - self.plan_t0, x)
            self._decide(t, "lost", cost=cost)
            self.mode = None  # the fallback below is logged as its own decision
        if self.mode == "wait":
            return self.brake(t, x)
        fast = self._fast(x)
        if not fast:
            self.fast_since = None
        elif self.fast_since is None:
            self.fast_since = t
            self.mpc_spent = False  # knocked (thrown) since the MPC ran out: a new state, the MPC may try it again
        timed_out = fast and self.planner is not None and t - self.fast_since >= self.options.calm_budget
        if self.planner is None or (fast and not timed_out) or t < self.retry_at:
            self._set(t, "brake", cost=cost, energy=self._energy(x))
            return self.calm_brake(t, x) if fast else self.brake(t, x)
        if timed_out:  # the brake has not calmed it: plan from the fast state, within the planner's budget
            rates = np.asarray(x, dtype=float)[[self.model.nq + h for h in self.hinges]]
            self._decide(t, "calm_timeout", braked_s=t - self.fast_since, rates=[float(r) for r in rates])
            self.fast_since = None
        elif self._mpc_reaches(x):
            return self._start_mpc(t, x, cost)
        self._request_plan(t, x)
        return self.brake(t, x)

    def _law_done(self, t: float, cost: float) -> bool:
        """While the swing-up law acts: whether it has run ``law_budget`` s without a catch and a planner can take
        over (a ``law_failed`` decision; from then on the brake and the planner take every fall)."""
        if self.law_spent:
            return True
        if self.law_t0 is None:
            self.law_t0 = t
        ran = t - self.law_t0
        if self.planner is None or ran < self.options.law_budget:
            return False
        self.law_spent, self.mode = True, None  # the fallback is logged as its own decision next
        self._decide(t, "law_failed", ran_s=ran, cost=cost,
                     reason=f"no catch within {self.options.law_budget:g} s of the swing-up law")
        return True

    def _plan_holds(self, t: float, x) -> bool:
        """With ``cart_plans``: whether a plan is tracked, not over and not lost, or (a plan on its way, or after a
        failed one) the law follows a stored plan (:class:`~cartpole.supervise.lead_in.PlanLeadIn`), so that the catch
        waits for the plan's end (its TVLQR hands over there, as the plan designed from the start does)."""
        if not self.options.cart_plans:
            return False
        if self.mode in ("wait", "brake", None):  # None: a fallback about to be logged
            return isinstance(self.brake, PlanLeadIn) and self.brake.leads(t, x)
        return self.mode == "track" and t - self.plan_t0 < self.plan.trajectory.duration and not self._lost(t, x)

    def _mpc_reaches(self, x) -> bool:
        """Whether the swing-up MPC takes a calm ``x`` (nx,): there is one, it has not failed (run out of its budget)
        since the last catch or the last knock (a calm state turned fast), and the energy is at most ``mpc_energy``
        above the upright's and (with ``mpc_floor``) at most ``mpc_floor`` below it."""
        gap = self._energy(x) - self._energy(self.model.x_eq)
        floor = self.options.mpc_floor
        return (self.mpc is not None and not self.mpc_spent and gap <= self.options.mpc_energy
                and (floor is None or gap >= -floor))

    def _start_mpc(self, t: float, x, cost: float) -> np.ndarray:
        """The swing-up MPC takes over from ``x`` at ``t`` (reset: its solution from the upright's inputs, warmed
        in the loop); its ctrl (nu,)."""
        self.mpc_ms.extend(getattr(self.mpc, "solve_ms", None) or ())  # its reset forgets them
        self.mpc_over += len(getattr(self.mpc, "over_budget", None) or ())
        if callable(getattr(self.mpc, "reset", None)):
            self.mpc.reset()
        self.mpc_t0, self.mpc_ready, self.pending = t, t, None
        detail = self._prepare_mpc(t, x) if self.options.mpc_converge or self.mpc_design is not None else {}
        self._set(t, "mpc", cost=cost, energy=self._energy(x), **detail)
        return self._mpc_or_brake(t, x)

    def _mpc_or_brake(self, t: float, x) -> np.ndarray:
        """ctrl (nu,): the swing-up MPC's (called with the time since :attr:`mpc_t0`), or the brake while its
        take-over's solve is still charged (``mpc_converge``)."""
        if t < self.mpc_ready - 1e-12:
            return self.brake(t, x)
        return self.mpc(t - self.mpc_t0, x)

    def _prepare_mpc(self, t: float, x) -> dict:
        """With ``mpc_converge`` or :attr:`mpc_design`: converge the MPC's solution from (or design a new MPC for) the
        state predicted ``mpc_latency`` s (or ``charged_latency``) ahead of ``x`` (nx,) under the brake (``x`` itself
        when that rounds to no step), and charge its wall time: the MPC's clock starts at the predicted state's time,
        and it acts from the later of that and ``t`` plus the charge. Returns the ``mpc`` decision's details
        (``charged_s``, ``predicted_latency_s``, ``status``; ``converge_s`` and ``iterations`` for a converged
        solution; ``design_s``, and a chosen design's ``choice`` and ``predicted_return``, for a design)."""
        charged_latency = self.options.charged_latency
        lat = float(self.options.mpc_latency if charged_latency is None else charged_latency)
        steps = int(round(lat / self.model.dt))
        x_from = (np.asarray(x, dtype=float) if steps == 0
                  else model_rollout(self.model, self.brake, x, steps, t0=t)[0][-1])
        start = time.perf_counter()
        detail = self._design_mpc(x_from) if self.mpc_design is not None else self._converge_from(x_from)
        wall = time.perf_counter() - start
        charged = wall if charged_latency is None else float(charged_latency)
        self.mpc_t0 = t + steps * self.model.dt
        self.mpc_ready = max(t + charged, self.mpc_t0)
        if self.mpc_design is None:
            self.mpc_converge_s.append(wall)
            return {"converge_s": wall, "charged_s": charged, "predicted_latency_s": lat, **detail}
        return {"design_s": wall, "charged_s": charged, "predicted_latency_s": lat, **detail}

    def _converge_from(self, x) -> dict:
        """Converge :attr:`mpc`'s solution from ``x`` (nx,): ``iterations`` and ``status``."""
        try:
            info = self.mpc.converge(x)
        except CartPoleError as exc:  # a prediction that is not finite: the MPC from the upright's inputs
            self.mpc.reset()
            info = {"iterations": 0, "status": str(exc)}
        return {"iterations": int(info["iterations"]), "status": str(info["status"])}

    def _design_mpc(self, x) -> dict:
        """:attr:`mpc` designed afresh from ``x`` (nx,) by :attr:`mpc_design`: ``status``, and a chosen design's
        ``choice`` and ``predicted_return`` (its ``as_dict()``)."""
        try:
            mpc = self.mpc_design(x)
        except CartPoleError as exc:  # e.g. a prediction that is not finite: the previous MPC goes on
            return {"status": f"design failed, the previous MPC kept: {exc}"}
        self.mpc = mpc  # the previous one's step times were kept at the take-over (_start_mpc)
        record = mpc.as_dict() if callable(getattr(mpc, "as_dict", None)) else {}
        return {"status": "designed", **{k: record[k] for k in ("choice", "predicted_return") if k in record}}

    def _mpc_done(self, t: float, x, cost: float) -> bool:
        """While the swing-up MPC acts: whether it has failed (``mpc_budget`` s without a catch: the brake and the
        planner until the next catch or knock; or the energy more than ``mpc_energy`` above the upright's: knocked
        again, the MPC takes it once calmed): an ``mpc_failed`` decision."""
        ran = t - self.mpc_t0
        out = self._energy(x) - self._energy(self.model.x_eq) > self.options.mpc_energy  # knocked again
        if ran < self.options.mpc_budget and not out:
            return False
        self.mpc_spent, self.mode = not out, None  # knocked: calmed, then the MPC again; the fallback logged next
        if self.mpc_spent:  # only a later knock (calm, then fast) makes it a new state for the MPC
            self.fast_since = t if self._fast(x) else None
        why = "the energy rose above the MPC's band" if out else f"no catch within {self.options.mpc_budget:g} s"
        self._decide(t, "mpc_failed", ran_s=ran, cost=cost, energy=self._energy(x), reason=why)
        return True

    def summary(self) -> dict:
        """JSON-ready: ``decisions``, ``plans``, ``plan_failures``, ``plan_s`` (each plan's wall time), ``rho``,
        ``warm_plans`` (plans made from a library's warm start) and ``library_plans`` (plans in the library at the
        end, or None without one), ``prepare_s`` (the planner's warm-up in this process before the first worker,
        :meth:`prepare`, s; None when there was none), ``unreachable`` (each state no swing-up was found from within
        the budget: ``t``, ``x0``, the planner's ``reason``; and each stall of the swing-up law, its ``reason``),
        ``mpc_ms`` (the swing-up MPC's wall time per control step: ``median`` and ``max`` ms, ``steps``,
        ``over_budget``: the steps over ``mpc_step_budget`` that applied the previous solution's shifted input, and
        ``budget_ms``, None without a budget; None without an MPC step), ``mpc_converge_s`` (the wall time of each
        take-over's solve with ``mpc_converge``, s)."""
        unreachable = [{"t": d.t, "x0": d.detail.get("x0"), "reason": d.detail.get("reason")}
                       for d in self.decisions if d.kind in ("plan_failed", "stalled")]
        return {"unreachable": unreachable, "decisions": [d.to_dict() for d in self.decisions], "plans": self.plans,
                "plan_failures": self.failures, "plan_s": list(self.plan_seconds), "rho": self.rho,
                "warm_plans": self.warm_plans, "library_plans": None if self.library is None else len(self.library),
                "prepare_s": self.prepare_s, "mpc_ms": self._mpc_ms(), "mpc_converge_s": list(self.mpc_converge_s)}

    def _mpc_ms(self) -> dict | None:
        """The swing-up MPC's per-step wall time (``median``, ``max`` ms, ``steps``) and its steps over
        ``mpc_step_budget`` (``over_budget``, ``budget_ms``) over the run, or None."""
        ms = self.mpc_ms + list(getattr(self.mpc, "solve_ms", None) or ())
        if not ms:
            return None
        over = self.mpc_over + len(getattr(self.mpc, "over_budget", None) or ())
        budget = self.options.mpc_step_budget
        return {"median": float(np.median(ms)), "max": float(np.max(ms)), "steps": len(ms), "over_budget": over,
                "budget_ms": None if budget is None else 1e3 * budget}


def _warm(plan) -> bool:
    """Whether ``plan`` (a SwingupPlan) came from its warm start (its chosen solve is a ``warm <objective>`` stage)."""
    attempts = getattr(getattr(plan, "solve_info", None), "attempts", ()) or ()
    return any(a.chosen and a.stage.startswith("warm ") for a in attempts)


def hinge_driven(model: CartPoleModel) -> bool:
    """Whether every actuator of ``model`` drives a hinge (the acrobot), so that :func:`supervisor_for` gives it
    :func:`hinge_options`: calmed by the energy drain, swung up by the DDP MPC, planned (warm from knots, re-planned
    as it goes) only below ``mpc_floor`` or after the MPC failed."""
    return all(int(j) in model.hinges for j in model.params.actuated)


def _bounded_plan_model(plant: Plant) -> CartPoleModel:
    """The plant's model within :func:`~cartpole.models.planning_limits`' bounds (the plant's own model when its file
    bounds every motor and the rail)."""
    model = plant_model(plant)
    bounded, _ = planning_limits(model.params)
    return model if bounded is model.params else build_model(bounded)


def hinge_options(**changes) -> SupervisorOptions:
    """The settings :func:`supervisor_for` gives a model driven at a hinge (the acrobot) when it is given none, with
    ``changes`` (:class:`SupervisorOptions` fields, e.g. ``charged_latency``, ``mpc_floor=None``) on top: the swing-up
    MPC for every calm state down to :data:`HINGE_MPC_FLOOR` below the upright's energy (``swingup_mpc``,
    ``mpc_floor``; with ``mpc_floor=None`` hanging at rest too, for an MPC of a task's objective, which pumps); calm
    means at or below the upright's energy, :data:`HINGE_CALM_ENERGY` (``calm_energy``), reached by the energy drain
    (``calm_drain``, down to :data:`DRAIN_MARGIN` above it) and below it the soft brake of :data:`HINGE_BRAKE_TIME`
    (``calm_brake_time``), for at most :data:`HINGE_CALM_BUDGET` s (``calm_budget``); and for the planner, which acts
    below the floor and once the MPC has failed (``mpc_failed``: no catch within ``mpc_budget``) until the next catch
    or knock:
    warm starts from the nearest knots of the stored plans (``warm_tails``), no exact-discrete re-solve
    (``exact_plans=False``), re-planned every :data:`HINGE_REPLAN_EVERY` s while tracked (``replan_every``).

    Returns
    -------
    SupervisorOptions
    """
    return SupervisorOptions(replan_every=HINGE_REPLAN_EVERY, exact_plans=False, calm_energy=HINGE_CALM_ENERGY,
                             calm_budget=HINGE_CALM_BUDGET, warm_tails=True, calm_brake_time=HINGE_BRAKE_TIME,
                             calm_drain=True, swingup_mpc=True, mpc_floor=HINGE_MPC_FLOOR).replace(**changes)


def _mpc_objective(plan: PlanOptions | None):
    """The swing-up MPC's running objective: the plan's when it names a running one (a name other than ``time``, or
    a callable), else None (the tracking of upright)."""
    objective = None if plan is None else plan.objective
    if objective is None or (isinstance(objective, str) and objective in ("time", "tracking")):
        return None
    return objective if isinstance(objective, str) or callable(objective) else None


def swingup_mpc(params, model: CartPoleModel, period: float | None = None, *,
                step_budget: float | None = None, objective=None, horizon: float | None = None,
                iterations: int = 1) -> DDPMPCController:
    """The supervisor's swing-up MPC (``swingup_mpc``): the DDP MPC of the tracking objective (or ``objective``), no
    offline plan, ``iterations`` DDP iterations a control period (default one), ``horizon`` s ahead (default
    :data:`MPC_HORIZON`).

    Parameters
    ----------
    params : CartPoleParams
        The MJCF MuJoCo runs (its step, ctrl ranges and joint ranges bound the MPC).
    model : CartPoleModel
        The planning model.
    period : float, optional
        Control period in s, a whole number of MJCF steps (default one step).
    step_budget : float, optional
        s of wall time a step may take before the previous solution's shifted input is applied instead
        (``SupervisorOptions.mpc_step_budget``); None: unbounded.
    objective : str or callable, optional
        The MPC's running objective (``MPCOptions.objective``: a ``dmc_*`` reward, ``effort``, ...); None (default)
        the tracking of upright.
    horizon : float, optional
        s the MPC looks ahead (``SupervisorOptions.mpc_horizon``); None: :data:`MPC_HORIZON`.
    iterations : int
        DDP iterations a control period (``SupervisorOptions.mpc_iterations``).

    Returns
    -------
    DDPMPCController
        Called ``u = mpc(t, x)`` with ``t`` the time since it took over (s), ``x`` (nx,), ``u`` (nu,) ctrl.
    """
    opts = MPCOptions(solver="ddp", seed_plan=False, horizon=MPC_HORIZON if horizon is None else horizon,
                      iterations=iterations, objective=objective,
                      period=float(params.timestep) if period is None else float(period))
    return DDPMPCController(model, params, options=opts, step_budget=step_budget)


def _at_period(sup: Supervisor, period: float | None) -> Supervisor:
    """``sup`` with its control :attr:`Supervisor.period` set."""
    sup.period = period
    return sup


def supervisor_for(plant: Plant = None, plan_model: CartPoleModel | None = None, *, period: float | None = None,
                   plan: PlanOptions | None = None, options: SupervisorOptions | None = None,
                   basin_cache: BasinCache | None = None, basin_of: Callable | None = None,
                   library: PlanLibrary | None = None, catch_R=None) -> Supervisor:
    """The supervisor for a cart-pole: its swing-up catch and verified basin, the brake, the energy law where it
    applies (one pole driven by the cart; a pendulum driven at its hinge:
    :func:`~cartpole.supervise.pump.hinge_swingup`),
    else the planner.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The MJCF MuJoCo runs (its ctrl ranges clip every law).
    plan_model : CartPoleModel, optional
        The planning model (default the MJCF's own within :func:`cartpole.models.planning_limits`' bounds, as the
        command line plans: a stated default ``|ctrl|`` bound on a motor without ctrlrange, and on an unlimited rail;
        a model given here is used as it is).
    period : float, optional
        Control period in s (default every physics step); the catch and the plans' TVLQR are designed over it.
    plan : PlanOptions, optional
        The planner's settings (default :class:`~cartpole.planning.options.PlanOptions`); its running objective is the
        swing-up MPC's too (e.g. ``dmc_acrobot_swingup``, as :func:`cartpole.apps.envscore.supervised` sets).
    options : SupervisorOptions, optional
        Default ``SupervisorOptions()``; on a model driven at a hinge (the acrobot) :func:`hinge_options`: a calm
        state (at or below the upright's energy) swung up by the DDP MPC (``swingup_mpc``, :func:`swingup_mpc`):
        minimising ``plan``'s objective when it names a running one, from every calm state, hanging at rest too
        (``mpc_floor=None``); else the tracking of upright, down to :data:`HINGE_MPC_FLOOR` below the upright's
        energy. The energy drain and the soft brake calm a faster state first; the planner (warm from the knots of
        ``library``'s plans, re-planned as it is tracked) takes the states below the floor, and any after the MPC
        has failed, until the next catch or knock. Options given here are used as they are (no hinge defaults: start
        from :func:`hinge_options`). With ``cart_plans`` on one pole driven by the cart: the planner, warm from
        ``library``, with the energy law as the law meanwhile (and after a failed or lost plan), when the library
        holds a plan; else the energy law alone.
    basin_cache : BasinCache, optional
        Where the catch's basin estimate is kept (default the on-disk cache).
    basin_of : callable, optional
        ``basin_of(catch) -> BasinEstimate`` instead of ``basin_cache`` (a caller's own cache and progress).
    library : PlanLibrary, optional
        The planner's warm starts (:class:`~cartpole.planning.library.PlanLibrary`; default the one stored in the
        user cache for ``model``, empty when none was built; with ``cart_plans`` the one of ``plan.objective``:
        :meth:`~cartpole.planning.library.PlanLibrary.load`); the supervisor's own plans join it in memory.
    catch_R : (nu, nu) array or float, optional
        The catch's input weight (default :data:`~cartpole.control.switching.SWINGUP_CATCH_R`), e.g. one designed for
        the rig's sensors (:func:`cartpole.apps.margins.noise_limited_catch`); the plans' own catches take it too.

    Returns
    -------
    Supervisor
    """
    params = plant_params(plant)
    model = _bounded_plan_model(plant) if plan_model is None else plan_model
    catch = LinearFeedback.for_model(model, R=SWINGUP_CATCH_R if catch_R is None else catch_R, period=period)
    if basin_of is None:
        cache = BasinCache.on_disk() if basin_cache is None else basin_cache
        basin = cache.get(params, catch)
    else:
        basin = basin_of(catch)
    rho = basin.rho
    opts = SupervisorOptions() if options is None else options
    if options is None and hinge_driven(model):  # driven at a hinge (the acrobot): the MPC from calm states
        opts = hinge_options(mpc_floor=HINGE_MPC_FLOOR if _mpc_objective(plan) is None else None)
    if opts.plan_in_worker is None:  # its planner's plans pickle: in a worker wherever the platform can fork
        opts = opts.replace(plan_in_worker=fork_available())
    inertia, _ = joint_inertia_and_authority(params, np.asarray(model.x_eq, dtype=float))
    brake = PassiveBrake(model, inertia, opts.brake_time, catch.u_limits)
    calm_brake = (None if opts.calm_brake_time is None else
                  PassiveBrake(model, inertia, opts.calm_brake_time, catch.u_limits))
    try:
        check_single_pole(model)
    except EnergyShapingModelError:
        if pendulum_driven_at_hinge(model):  # one pole on a driven hinge: its optimal swing-up from anywhere, no plan
            swingup = hinge_swingup(model, catch.u_limits, period)
            sup = Supervisor(model, catch, rho, brake, swingup=swingup, options=opts, basin=basin)
            return _at_period(sup, period)
        if opts.calm_drain:  # the drain down to the calm energy, the calming brake below it (a chain: a joint the
            # motor does not drive; a pendulum on its driven hinge pumps, above)
            calm_brake = EnergyDrain(model, target=DRAIN_MARGIN + (0.0 if opts.calm_energy is None else
                                                                   opts.calm_energy),
                                     below=brake if calm_brake is None else calm_brake, u_limits=catch.u_limits)
        planner = _swingup_planner(params, model, plan, opts, period, catch_R)
        lib = PlanLibrary.load(model) if library is None else library
        sup = Supervisor(model, catch, rho, brake, planner=planner, options=opts, basin=basin, library=lib,
                         calm_brake=calm_brake)
        sup.mpc = (swingup_mpc(params, model, period, step_budget=opts.mpc_step_budget, objective=_mpc_objective(plan),
                               horizon=opts.mpc_horizon, iterations=opts.mpc_iterations)
                   if opts.swingup_mpc else None)
        return _at_period(sup, period)
    law = EnergyShapingController(model)
    lib = None
    if opts.cart_plans:  # plans warm from the library's, the energy law meanwhile (SupervisorOptions.cart_plans)
        lib = PlanLibrary.load(model, objective=None if plan is None else plan.objective) if library is None \
            else library
    if lib is not None and len(lib):  # the library's plan followed meanwhile from a start near it, else the law
        lead = _lead_in(params, model, lib, law, catch, period)
        sup = Supervisor(model, catch, rho, lead, planner=_cart_planner(params, model, plan, opts, period, catch_R),
                         options=opts, basin=basin, library=lib, calm_brake=lead)
        return _at_period(sup, period)
    planner = _swingup_planner(params, model, plan, opts, period, catch_R)  # once the law runs out (law_budget)
    return _at_period(Supervisor(model, catch, rho, brake, swingup=law, planner=planner, options=opts, basin=basin),
                      period)


def _lead_in(params, model: CartPoleModel, lib: PlanLibrary, law, catch: LinearFeedback,
             period: float | None) -> PlanLeadIn:
    """With ``cart_plans``: the law while a plan is made, :class:`~cartpole.supervise.lead_in.PlanLeadIn` along the
    library's plan from hanging (from a start near it: an episode's, at t = 0), the energy ``law`` elsewhere."""
    return PlanLeadIn(model, lib.nearest(model.x_hanging)[0].trajectory, law, catch,
                      float(params.timestep) if period is None else float(period))


def _cart_planner(params, model: CartPoleModel, plan: PlanOptions | None, opts: SupervisorOptions,
                  period: float | None, catch_R) -> Callable:
    """With ``cart_plans``: the planner (a sparse task's at the MJCF's step by
    :func:`~cartpole.planning.box_tail.box_tail_planner`, which keeps the stored entry plans' box entry, else
    :func:`_swingup_planner`)."""
    if is_sparse_task(None if plan is None else plan.objective) and (
            period is None or abs(float(period) - float(params.timestep)) < 1e-12):
        return box_tail_planner(params, model, plan.objective, catch_R=catch_R, options=plan)
    return _swingup_planner(params, model, plan, opts, period, catch_R)


def _swingup_planner(params, model: CartPoleModel, plan: PlanOptions | None, opts: SupervisorOptions,
                     period: float | None, catch_R) -> Callable:
    """``planner(x0, guess=None, cold=True) -> SwingupPlan``: :func:`~cartpole.planning.trajopt.trajopt_swingup` on
    ``model`` with ``plan``'s settings (default ``PlanOptions()``), its searches bounded by ``opts.plan_budget`` s,
    without the exact-discrete re-solve unless ``opts.exact_plans``."""
    plan_opts = PlanOptions() if plan is None else plan
    budget = opts.plan_budget if plan_opts.search_s is None else min(plan_opts.search_s, opts.plan_budget)
    plan_opts = plan_opts.replace(search_s=budget)  # bounded planning, whatever the plan options say
    if not opts.exact_plans:
        plan_opts = plan_opts.replace(exact_discrete=False)

    def planner(x0, guess=None, cold=True):
        return trajopt_swingup(params, x0=tuple(x0), plan_model=model, options=plan_opts, period=period,
                               guess=guess, catch_R=catch_R, cold=cold)
    return planner
