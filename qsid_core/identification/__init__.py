"""Identification: least squares and bias-compensated LS from quantized moments, and Theorem 1's large-data prediction.

Every public name of this subpackage is listed in ``__all__``; import from here, not from its modules."""

from __future__ import annotations

from .edmd import (
    KoopmanModel,
    LiftedMoments,
    edmd,
    exact_lifted_moments,
    lifted_error,
    prediction_error,
    prediction_errors,
    quantized_lifted_moments,
    quantized_lifted_realizations,
)
from .edmd_limit import LARGE_DATA_HYPOTHESES, LargeDataLimit, error_moments, large_data_limit
from .identify import ESTIMATORS, Identified, identify, least_squares, mean_std_of_known, relative_errors
from .lifting import LIFTINGS, Lifting, MonomialLifting, RBFLifting, bernoulli_shifted, parse_lifting
from .theorem1 import noise_covariance, theorem1_prediction

__all__ = [
    "ESTIMATORS",
    "Identified",
    "KoopmanModel",
    "LARGE_DATA_HYPOTHESES",
    "LIFTINGS",
    "LargeDataLimit",
    "LiftedMoments",
    "Lifting",
    "MonomialLifting",
    "RBFLifting",
    "bernoulli_shifted",
    "edmd",
    "error_moments",
    "exact_lifted_moments",
    "identify",
    "large_data_limit",
    "least_squares",
    "lifted_error",
    "mean_std_of_known",
    "noise_covariance",
    "parse_lifting",
    "prediction_error",
    "prediction_errors",
    "quantized_lifted_moments",
    "quantized_lifted_realizations",
    "relative_errors",
    "theorem1_prediction",
]
