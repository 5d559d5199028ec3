"""MJCF -> parameters -> kinematics -> symbolic CasADi model -> equilibria -> exact continuous and discrete linearisation."""
from cartpole.models.params import (SHIPPED_MJCF, SUPPORTED_INTEGRATORS, CartPoleParams, MJCFError,
                                    load_model, mujoco_model, mujoco_warnings, read_params)
from cartpole.models.urdf import AddedActuator, URDFError, URDFImport, import_urdf, is_urdf, urdf_session
from cartpole.models.friction import (DEFAULT_FRICTION_WIDTH, MAX_CONSTRAINT_FRICTION_DOFS, FrictionConstraint,
                                      FrictionWidthError, check_width, constraint_friction_force,
                                      friction_treatment,
                                      friction_constraint, smooth_friction)
from cartpole.models.kinematics import Kinematics, forward_kinematics, forward_kinematics_np, quat_to_mat
from cartpole.models.discretize import MAX_PERIOD, HoldModel, PeriodError, hold_model, steps_per_period
from cartpole.models.contacts import (CONTACT_MARGIN, ContactError, ContactPair, ContactReport,
                                      check_equilibrium_contacts, contact_report)
from cartpole.models.symbolic import (CartPoleModel, Equations, build_model, equations, state_error,
                                      wrap_angle)
from cartpole.models.plant import Plant, PlantError, is_plant, linearize, plant_model, plant_params
from cartpole.models.limits import MotorDrive, motor_drive
from cartpole.models.limits import (START_SNAP, LimitsError, PlanningLimits, StartMove, bounded_model, chain_length,
                                    default_cart_max, default_u_max, planning_limits, start_on_range)

__all__ = ["SHIPPED_MJCF", "SUPPORTED_INTEGRATORS", "CartPoleParams", "MJCFError", "load_model", "mujoco_warnings",
           "read_params", "mujoco_model", "AddedActuator", "URDFError", "URDFImport", "import_urdf", "is_urdf",
           "urdf_session",
           "CartPoleModel", "Equations", "build_model", "equations", "linearize", "state_error", "wrap_angle",
           "Kinematics", "forward_kinematics", "forward_kinematics_np", "MAX_PERIOD", "HoldModel", "PeriodError",
           "hold_model", "steps_per_period", "DEFAULT_FRICTION_WIDTH", "FrictionWidthError", "check_width",
           "smooth_friction", "quat_to_mat", "MAX_CONSTRAINT_FRICTION_DOFS", "FrictionConstraint",
           "constraint_friction_force", "friction_constraint", "friction_treatment", "CONTACT_MARGIN", "ContactError",
           "ContactPair", "ContactReport", "check_equilibrium_contacts", "contact_report"]
__all__ += ["START_SNAP", "LimitsError", "PlanningLimits", "StartMove", "bounded_model", "chain_length", "default_cart_max",
            "default_u_max", "planning_limits", "start_on_range"]
__all__ += ["Plant", "PlantError", "is_plant", "plant_model", "plant_params"]
__all__ += ["MotorDrive", "motor_drive"]
