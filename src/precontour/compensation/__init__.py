"""Pre-compensation: new axis commands whose predicted contour errors cancel.

- :mod:`.precompensate` -- :func:`compensate`, contour (orientation first, then tool tip; spec
  section 6) or the tracking-error baseline, with optional iteration.
"""

from .precompensate import METHODS, CompensationResult, compensate

__all__ = ["METHODS", "CompensationResult", "compensate"]
