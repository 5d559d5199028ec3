"""cartpole: model-based control of the cart-pole, derived from an MJCF and proven in MuJoCo.

Quick start::

    import cartpole as cp
    model = cp.build_model()                 # shipped MJCF -> symbolic CasADi model
    A, B = model.linearize()                 # exact, at upright rest
    K, S, E = cp.lqr(A, B, cp.Q_LAB, cp.R_LAB)

The names below are imported on first use (PEP 562), so that ``import cartpole`` (and the command line, which lives
inside the package) costs almost nothing before a command knows what it needs: ``cartpole sweep --workers 2`` starts
its workers' fork server while this process is still importing NumPy, SciPy, CasADi and MuJoCo.
"""
import importlib
import os
import sys
import types

# Offscreen rendering needs MUJOCO_GL set before mujoco is first imported; default to headless EGL (works
# with and without a display) unless the user chose a backend or already imported mujoco.
if "mujoco" not in sys.modules:
    os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"

#: Public name -> the module it comes from (a subpackage is its own module).
_EXPORTS = {
    "control": "cartpole.control", "models": "cartpole.models", "sim": "cartpole.sim",
    "validation": "cartpole.validation",
    "CartPoleError": "cartpole.errors",
    "Q_LAB": "cartpole.lqr", "R_LAB": "cartpole.lqr", "LQRError": "cartpole.lqr", "dlqr": "cartpole.lqr",
    "lqr": "cartpole.lqr",
    "SHIPPED_MJCF": "cartpole.models", "CartPoleModel": "cartpole.models", "CartPoleParams": "cartpole.models",
    "MJCFError": "cartpole.models", "build_model": "cartpole.models", "read_params": "cartpole.models",
    "Rollout": "cartpole.sim", "replay": "cartpole.sim", "simulate": "cartpole.sim",
    "watch": "cartpole.apps.live",
}

#: The exports that are subpackages themselves (every other export is a name inside its module).
_SUBPACKAGES = ("control", "models", "sim", "validation")

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    """Import a public name on first use (PEP 562) and keep it in the package namespace."""
    target = _EXPORTS.get(name)
    if target is None:
        raise AttributeError(f"module 'cartpole' has no attribute {name!r}")
    module = importlib.import_module(target)
    value = module if name in _SUBPACKAGES else getattr(module, name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))


class _Package(types.ModuleType):
    """The package's module type: importing the subpackage ``cartpole.lqr`` does not hide the function ``lqr`` (the
    import system binds a submodule on its parent; the public name stays the function, as it always was)."""

    def __setattr__(self, name, value):
        if name in _EXPORTS and name not in _SUBPACKAGES and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
