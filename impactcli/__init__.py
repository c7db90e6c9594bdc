"""impactcli — offline replay of the adaptive impact detector of Makarov et al. 2014.

Data flows one way: ``io`` (readers) → ``model`` (identification, residual) →
``detect`` (adaptive evaluator, static detectors, events) → ``outputs``
(timeline JSON, report, Rerun). ``cli`` only parses options and chooses exit codes.
"""

__version__ = "0.1.0"
TOOL_NAME = "impactcli"

__all__ = ["TOOL_NAME", "__version__"]
