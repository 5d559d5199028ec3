"""MuJoCo on the MJCF: closed-loop runs logged every physics step (:mod:`~cartpole.sim.rollout`), their exact
open-loop replay, many linear-feedback runs at once (:mod:`~cartpole.sim.batch`), and the closed loop's settings as
one value (:mod:`~cartpole.sim.options`: :class:`~cartpole.sim.options.LoopOptions`, and the base every stage's
options share)."""
from cartpole.sim.batch import random_starts, simulate_batch_linear
from cartpole.sim.options import LoopError, LoopOptions
from cartpole.sim.rig import Rig, RigError, RigRun, build_rig, delay_steps
from cartpole.sim.rollout import (Rollout, SimOptions, cart_body, ctrl_bounds, make_mujoco, replay, replays_exactly,
                                  simulate, source_path)
from cartpole.sim.disturbance import (KNOCK_ENERGY, UPRIGHT_BAND, DisturbanceError, Knockdown, KnockdownForce,
                                      KnockRecord, Reset, ResetForce, Throw, ThrowForce,
                                      swingup_energy)

__all__ = ["LoopError", "LoopOptions", "Rollout", "SimOptions", "cart_body", "ctrl_bounds", "make_mujoco", "replay",
           "replays_exactly", "simulate", "source_path", "random_starts", "simulate_batch_linear",
           "Rig", "RigError", "RigRun", "build_rig", "delay_steps", "UPRIGHT_BAND", "DisturbanceError", "Knockdown",
           "KnockdownForce", "Throw", "ThrowForce", "KNOCK_ENERGY", "KnockRecord", "swingup_energy",
           "Reset", "ResetForce"]
