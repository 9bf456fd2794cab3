"""Prediction: what the drives will do with the commands, before the machine moves.

- :mod:`.splinefit` -- minimum-jerk C3 quintic spline of each axis within an encoder
  resolution (spec section 3);
- :mod:`.tracking` -- closed-form tracking error of each axis for any stable linear error
  model (spec section 4);
- :mod:`.contour` -- tool-tip and orientation contour errors: closest points on the reference
  curves (spec section 5).
"""

from .contour import ContourErrors, ReferencePath, contour_errors
from .splinefit import AxisFits, SplineFit, fit_axes, fit_min_jerk
from .tracking import AxisPrediction, TrackingError, predict_tracking, tracking_error

__all__ = ["AxisFits", "AxisPrediction", "ContourErrors", "ReferencePath", "SplineFit",
           "TrackingError", "contour_errors", "fit_axes", "fit_min_jerk", "predict_tracking",
           "tracking_error"]
