"""System identification: logged runs, parameters by MJCF name, the multiple-shooting fit with its uncertainty,
the fitted MJCF, and excitation signals (``cartpole excite`` / ``cartpole identify``; docs/identify.md)."""
from cartpole.identify.excite import Excitation, ExciteError, multisine, natural_frequencies
from cartpole.identify.fit import FitError, FitResult, Simulation, fit, identifiability_warnings, simulate_log
from cartpole.identify.logs import LogError, RunLog, read_csv_log, read_json_log, read_log
from cartpole.identify.mjcf import FittedMJCFError, check_fitted, fitted_text, write_fitted_mjcf
from cartpole.identify.parameters import (Parameter, ParameterError, default_names, parse_parameters, sample_step,
                                          with_values)

__all__ = ["Excitation", "ExciteError", "FitError", "FitResult", "FittedMJCFError", "LogError", "Parameter",
           "ParameterError", "RunLog", "Simulation", "check_fitted", "default_names", "fit",
           "fitted_text", "identifiability_warnings", "multisine", "natural_frequencies", "parse_parameters",
           "read_csv_log", "read_json_log", "read_log", "sample_step", "simulate_log", "with_values",
           "write_fitted_mjcf"]
