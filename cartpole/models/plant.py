"""The plant, however a caller names it: every public function that needs the cart-pole takes one argument ``plant``
and resolves it here, so a path, the parameters read from it and the symbolic model built from them are accepted
alike everywhere (python-control's ``sys``, Drake's ``plant``).

``plant`` is one of

- ``None``: the shipped asset (:data:`~cartpole.models.params.SHIPPED_MJCF`);
- a path (``str`` or :class:`os.PathLike`) to an MJCF or URDF file;
- :class:`~cartpole.models.params.CartPoleParams` (what :func:`~cartpole.models.params.read_params` returns);
- :class:`~cartpole.models.symbolic.CartPoleModel` (what :func:`~cartpole.models.symbolic.build_model` returns).

:func:`plant_model` is the resolver: it returns the model (built once from parameters or a path, a model as it
is); :func:`plant_params` is its cheap half for the callers that need only the parameters (MuJoCo runs), so that
they do not derive the symbolic model they never use.
"""
from __future__ import annotations

import os
from typing import Union

from cartpole.errors import CartPoleError
from cartpole.models.discretize import steps_per_period
from cartpole.models.params import CartPoleParams, read_params
from cartpole.models.symbolic import CartPoleModel, build_model

#: What a ``plant`` argument may be (see the module's docstring).
Plant = Union[None, str, os.PathLike, CartPoleParams, CartPoleModel]


class PlantError(CartPoleError, TypeError):
    """A ``plant`` argument that is none of a path, CartPoleParams or CartPoleModel."""


def is_plant(value) -> bool:
    """True when ``value`` is a plant (a path, :class:`CartPoleParams` or :class:`CartPoleModel`; None is too).

    Parameters
    ----------
    value : object

    Returns
    -------
    bool
    """
    return value is None or isinstance(value, (str, os.PathLike, CartPoleParams, CartPoleModel))


def plant_params(plant: Plant = None) -> CartPoleParams:
    """The parameters of ``plant`` without building its symbolic model.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        MJCF or URDF path (None: the shipped asset), parameters, or a model (its ``params``).

    Returns
    -------
    CartPoleParams

    Raises
    ------
    PlantError
        For anything else.
    MJCFError
        For a file that cannot be read as a cart-pole.
    """
    if isinstance(plant, CartPoleModel):
        return plant.params
    if isinstance(plant, CartPoleParams):
        return plant
    if plant is None or isinstance(plant, (str, os.PathLike)):
        return read_params(plant)
    raise PlantError(f"plant is a {type(plant).__name__}; give an MJCF or URDF path (None for the shipped asset), "
                     "the CartPoleParams of read_params or the CartPoleModel of build_model.")


def plant_model(plant: Plant = None) -> CartPoleModel:
    """The symbolic model of ``plant``: a :class:`CartPoleModel` as it is, anything else built with
    :func:`~cartpole.models.symbolic.build_model` (the MJCF's own step and integrator).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        MJCF or URDF path (None: the shipped asset), parameters, or a model.

    Returns
    -------
    CartPoleModel

    Raises
    ------
    PlantError
        For anything else.
    MJCFError
        For a file that cannot be read as a cart-pole.
    """
    if isinstance(plant, CartPoleModel):
        return plant
    return build_model(plant_params(plant))


def linearize(plant: Plant = None, x=None, u=None, *, discrete: bool = False,
              period: float | None = None) -> tuple:
    """Exact Jacobians of ``plant`` at the state ``x`` and the ctrl ``u``: the package's one linearisation shape,
    the same pair as :meth:`CartPoleModel.linearize <cartpole.models.symbolic.CartPoleModel.linearize>`.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The cart-pole (:func:`plant_model`).
    x : (nx,) array, optional
        State ``[qpos, qvel]`` (m, rad, m/s, rad/s); default the upright equilibrium ``x_eq``.
    u : (nu,) array, optional
        Ctrl; default ``u_eq``.
    discrete : bool
        False: the continuous ``(A, B)`` of ``f``. True: ``(Ad, Bd)`` of one step of the MJCF's integrator.
    period : float, optional
        Control period in s, a whole number of physics steps: ``(Ad, Bd)`` of the exact discrete model over that
        hold (the ctrl held), whatever ``discrete`` says; one step is the same as ``discrete=True``.

    Returns
    -------
    A : (nx, nx) array
        ``A`` (1/s) or ``Ad`` (dimensionless).
    B : (nx, nu) array
        ``B`` per unit ctrl (per second) or ``Bd`` per unit ctrl.
    """
    model = plant_model(plant)
    steps = steps_per_period(period, model.dt)
    if steps > 1:
        return model.hold(steps).linearize(x, u)
    return model.linearize(x, u, discrete=discrete or period is not None)
