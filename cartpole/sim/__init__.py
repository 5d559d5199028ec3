"""MuJoCo on the MJCF: closed-loop runs logged every physics step (:mod:`~cartpole.sim.rollout`), their exact
open-loop replay, and many linear-feedback runs at once (:mod:`~cartpole.sim.batch`)."""
from cartpole.sim.batch import random_starts, simulate_batch_linear
from cartpole.sim.rollout import Rollout, cart_body, ctrl_bounds, make_mujoco, replay, replays_exactly, simulate, source_path

__all__ = ["Rollout", "cart_body", "ctrl_bounds", "make_mujoco", "replay", "replays_exactly", "simulate", "source_path",
           "random_starts", "simulate_batch_linear"]
