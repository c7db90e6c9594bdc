"""The rough rigid model (docs/method.md §2): structures, derivatives, identification, residuals.

Pure maths: nothing here prints; the only file read is the URDF a robot description
points at when it does not carry its text. The model file is read and written at the edge
(:mod:`impactcli.run.model_files`).
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
from .rigid import RigidModel
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
    "zero_phase_derivatives",
    "zero_phase_lowpass",
]
