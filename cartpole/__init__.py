"""cartpole: model-based control of the cart-pole, derived from an MJCF and proven in MuJoCo.

Quick start::

    import cartpole as cp
    model = cp.build_model()                 # shipped MJCF -> symbolic CasADi model
    A, B = cp.linearize(model)               # exact, at upright rest
    Q, R = cp.default_weights(model)         # 1 per slide, 10 per hinge, 0.1 per rate and per input
    K, S, E = cp.lqr(A, B, Q, R)
    K, S, E = cp.lqr(model)                  # the same design, on the plant (python-control's lqr(sys, Q, R))
    catch = cp.LinearFeedback.for_model(model)
    run = cp.simulate(model, catch, model.x_eq + [0, 0.1, 0, 0], 3.0)

Every function that needs the cart-pole takes it as ``plant``: an MJCF or URDF path (None: the shipped asset), the
:class:`CartPoleParams` of :func:`read_params`, or the :class:`CartPoleModel` of :func:`build_model`, alike.

This package top is the API: a notebook imports from ``cartpole`` only (``import cartpole as cp``), for each
workflow:

- the model: :func:`build_model`, :func:`read_params`, :func:`linearize`, :func:`plant_model`, :func:`plant_params`;
- LQR: :func:`lqr`, :func:`dlqr`, :func:`tvlqr`, :func:`default_weights`, :class:`LinearFeedback`
  (``LinearFeedback.for_model``, the one constructor of the upright LQR);
- the lab: :func:`run_lab`, :func:`run_pid_lab`, :func:`balances`, :func:`plot_lab`, :func:`watch`, its weights
  :data:`Q_LAB`, :data:`R_LAB`;
- swing-up, plan and track: :func:`run_swingup` (:class:`SwingupOptions`, each stage's options inside:
  :class:`PlanOptions`, :class:`MPCOptions`, :class:`EnergyOptions`, :class:`LoopOptions`), :func:`swingup_sweep`,
  :func:`trajopt_swingup`, :class:`EnergyShapingController`, :class:`SwitchingController`, :class:`TVLQRController`,
  :func:`run_feedforward` (:class:`FeedforwardOptions`);
- knocked down, it swings up again: :func:`supervisor_for` (:class:`Supervisor`, :class:`SupervisorOptions`),
  :class:`Knockdown`, :class:`Throw` (``LoopOptions(knockdown=..., throw=...)``), :func:`uptime_metrics`;
- simulate and replay: :func:`simulate` (:class:`SimOptions`), :func:`replay`, :func:`replays_exactly`,
  :class:`Rollout`, :class:`LoopOptions`;
- the rig and estimation: :func:`sensor_spec`, :class:`KalmanFilter`; margins: :func:`sampled_loop`,
  :func:`loop_margins`; identification: :func:`run_excite` (:class:`ExciteOptions`),
  :func:`run_identify`;
- export to C: :func:`run_export` (:class:`ExportOptions`), :func:`design_export`, :func:`load_design`,
  :func:`run_lockstep`;
- proof and figures: :func:`swingup_success`, :func:`summarize`, :func:`check_jacobians`, :func:`plot_swingup`,
  :func:`swingup_figure`, :func:`render_video` (:class:`VideoOptions`).

The names are imported on first use (PEP 562), so that ``import cartpole`` (and the command line, which lives
inside the package) costs almost nothing before a command knows what it needs: ``cartpole sweep --workers 2`` starts
its workers' fork server while this process is still importing NumPy, SciPy, CasADi and MuJoCo. The LQR subpackage
is :mod:`cartpole.riccati` (named for the equations it solves), so nothing shadows the function ``cartpole.lqr``.
"""
import importlib as _importlib
import os as _os
import sys as _sys

# Offscreen rendering needs MUJOCO_GL set before mujoco is first imported; default to headless EGL (works
# with and without a display) unless the user chose a backend or already imported mujoco.
if "mujoco" not in _sys.modules:
    _os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"

#: The module each public name comes from, by workflow (a name is looked up there on first use).
_SOURCES = {
    "cartpole.errors": ("CartPoleError",),
    "cartpole.models": ("SHIPPED_MJCF", "CartPoleModel", "CartPoleParams", "MJCFError", "Plant", "PlantError",
                        "build_model", "linearize", "plant_model", "plant_params", "read_params", "wrap_angle"),
    "cartpole.riccati": ("LQRError", "LQRResult", "TVLQRGains", "default_weights", "dlqr", "is_controllable",
                         "lqr", "tvlqr"),
    "cartpole.control": ("CascadedPID", "EnergyShapingController", "LinearFeedback", "SWINGUP_CATCH_R",
                         "SwitchingController", "TVLQRController"),
    "cartpole.estimation": ("KalmanFilter", "measurement_function", "sensor_spec"),
    "cartpole.estimation.kalman": ("process_noise",),
    "cartpole.analysis": ("continuous_loop", "loop_margins", "sampled_loop"),
    "cartpole.sim": ("Knockdown", "LoopOptions", "Rollout", "SimOptions", "Throw", "make_mujoco", "replay",
                     "replays_exactly", "simulate"),
    "cartpole.planning.options": ("PlanOptions",),
    "cartpole.planning.trajopt": ("trajopt_swingup",),
    "cartpole.control.energy": ("EnergyOptions", "model_scales"),
    "cartpole.mpc.options": ("MPCOptions",),
    "cartpole.supervise": ("Supervisor", "SupervisorOptions", "supervisor_for"),
    "cartpole.export": ("design_export", "load_design", "run_lockstep"),
    "cartpole.validation": ("BasinCache", "estimate_basin", "swingup_metrics", "swingup_success",
                             "uptime_metrics"),
    "cartpole.validation.jacobians": ("check_jacobians", "mujoco_fd_jacobians", "random_states"),
    "cartpole.validation.metrics": ("UPRIGHT_TOL", "held_upright", "summarize", "track_margin"),
    "cartpole.viz": ("VideoOptions", "VideoUnavailable", "plot_lab", "plot_swingup", "render_frame", "render_video"),
    "cartpole.viz.estimation_plot": ("estimation_figure",),
    "cartpole.viz.feedforward_plot": ("plot_feedforward",),
    "cartpole.viz.loop_plot": ("loop_figure",),
    "cartpole.viz.swingup_plot": ("swingup_figure",),
    "cartpole.apps.lab": ("Q_LAB", "R_LAB", "balances", "run_lab", "run_pid_lab"),
    "cartpole.apps.swingup": ("TRAJOPT_EXTRA", "SwingupOptions", "run_swingup"),
    "cartpole.apps.sweep": ("swingup_sweep",),
    "cartpole.apps.feedforward": ("FeedforwardOptions", "PlanFeedforward", "run_feedforward"),
    "cartpole.apps.margins": ("mujoco_stable",),
    "cartpole.apps.excite": ("ExciteOptions", "run_excite"),
    "cartpole.apps.identify": ("run_identify",),
    "cartpole.apps.export": ("ExportOptions", "run_export"),
    "cartpole.apps.live": ("watch",),
}

#: Public name -> the module it comes from.
_EXPORTS = {name: module for module, names in _SOURCES.items() for name in names}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    """Import a public name on first use (PEP 562) and keep it in the package namespace."""
    target = _EXPORTS.get(name)
    if target is None:
        raise AttributeError(f"module 'cartpole' has no attribute {name!r}")
    value = getattr(_importlib.import_module(target), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
