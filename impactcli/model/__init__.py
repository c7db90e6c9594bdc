"""The rough rigid model (docs/method.md §2): structures, derivatives, identification, residuals.

Pure maths: nothing here prints; the only file read is the URDF a robot description
points at (and :func:`read_model` / :func:`write_model`, the model file's edge).
"""

from .derivatives import (
    causal_derivatives,
    causal_lowpass,
    zero_phase_derivatives,
    zero_phase_lowpass,
)
from .identification import default_kind, identify, identify_many, identify_signals
from .identify_options import IdentifyOptions
from .residual import ResidualOptions, ResidualResult, compute_residual, momentum_observer
from .rigid import RigidModel, read_model, write_model
from .structures import KINDS

__all__ = [
    "KINDS",
    "IdentifyOptions",
    "ResidualOptions",
    "ResidualResult",
    "RigidModel",
    "causal_derivatives",
    "causal_lowpass",
    "compute_residual",
    "default_kind",
    "identify",
    "identify_many",
    "identify_signals",
    "momentum_observer",
    "read_model",
    "write_model",
    "zero_phase_derivatives",
    "zero_phase_lowpass",
]
