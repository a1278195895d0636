"""Identification: least squares and bias-compensated LS from quantized moments, and Theorem 1's large-data prediction.

Every public name of this subpackage is listed in ``__all__``; import from here, not from its modules."""

from __future__ import annotations

from .identify import ESTIMATORS, Identified, identify, least_squares, relative_errors
from .theorem1 import noise_covariance, theorem1_prediction

__all__ = [
    "ESTIMATORS",
    "Identified",
    "identify",
    "least_squares",
    "noise_covariance",
    "relative_errors",
    "theorem1_prediction",
]
