"""Pre-compensation: new axis commands whose predicted contour errors cancel.

- :mod:`.precompensate` -- :func:`compensate`, contour (orientation first, then tool tip; spec
  section 6) or the tracking-error baseline, with optional iteration.
- :mod:`.programmed_end` -- every compensated program ends at its programmed end point: the
  corrections taper to zero over a final rest, which a plan gets where it is too short.
- :mod:`.stops` -- learning against a nonlinear machine model (friction) where the linear model
  fails: stops, reversals, the final dwell.
"""

from .precompensate import METHODS, CompensationResult, compensate
from .stops import DEFAULT_LEARNING_PASSES, LearningReport, learn_at_stops

__all__ = ["METHODS", "CompensationResult", "compensate", "DEFAULT_LEARNING_PASSES",
           "LearningReport", "learn_at_stops"]
