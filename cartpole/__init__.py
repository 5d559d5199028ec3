"""cartpole: model-based control of the cart-pole, derived from an MJCF and proven in MuJoCo.

Quick start::

    import cartpole as cp
    model = cp.build_model()                 # shipped MJCF -> symbolic CasADi model
    A, B = model.linearize()                 # exact, at upright rest
    K, S, E = cp.lqr(A, B, cp.Q_LAB, cp.R_LAB)
"""
import os
import sys

# Offscreen rendering needs MUJOCO_GL set before mujoco is first imported; default to headless EGL (works
# with and without a display) unless the user chose a backend or already imported mujoco.
if "mujoco" not in sys.modules:
    os.environ.setdefault("MUJOCO_GL", "egl")

from cartpole import control, models, sim, validation  # noqa: E402
from cartpole.errors import CartPoleError
from cartpole.lqr import Q_LAB, R_LAB, LQRError, dlqr, lqr
from cartpole.models import SHIPPED_MJCF, CartPoleModel, CartPoleParams, MJCFError, build_model, read_params
from cartpole.sim import Rollout, replay, simulate

__version__ = "0.1.0"

__all__ = ["control", "models", "sim", "validation", "CartPoleError", "LQRError", "dlqr", "lqr", "SHIPPED_MJCF", "CartPoleModel", "CartPoleParams",
           "MJCFError", "build_model", "read_params", "Rollout", "replay", "simulate", "Q_LAB", "R_LAB"]
