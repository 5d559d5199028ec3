"""MuJoCo replay, metrics, Jacobian checks, plots and video: the proof of every control claim."""
from cartpole.validation.replay import Rollout, make_mujoco, replay, replays_exactly, simulate

__all__ = ["Rollout", "make_mujoco", "replay", "replays_exactly", "simulate"]
