"""Pre-compensation: new axis commands whose predicted contour errors cancel.

One public function, :func:`compensate` (``compensate(servo, trajectory, *, method, limits,
learn, ...)``), the servo first; its strategies are keywords and their code is the
package's own:

- :mod:`.precompensate` -- one compensation of a trajectory: contour (orientation first,
  then tool tip; spec section 6) or the tracking-error baseline, with optional iteration;
- :mod:`.pieces` -- long programs in overlapping pieces, linearly;
- :mod:`.within_limits` -- keeping the axis limits: local slow-downs and recompensation;
- :mod:`.stops` -- learning against a nonlinear machine model (friction) where the linear
  model fails: stops, reversals, the final dwell (how the kept command is picked:
  :class:`~.stops.Learner`); :mod:`.segments` -- learning a long program segment by segment;
- :mod:`.blocks` -- the judgement, block by block, of which command is worse;
- :mod:`.programmed_end` -- every compensated program ends at its programmed end point: the
  corrections taper to zero over a final rest, which a plan gets where it is too short.
"""

from ..defaults import DEFAULT_LEARNING_PASSES
from ..errors import warn_former
from .routes import METHODS, Compensation, compensate
from .options import LearningOptions, LimitOptions
from .precompensate import CompensationResult
from .stops import LearningReport

__all__ = ["compensate", "Compensation", "METHODS", "LearningOptions", "LimitOptions",
           "CompensationResult", "LearningReport", "DEFAULT_LEARNING_PASSES"]


def __getattr__(name):
    # learning has one entry, compensate(..., learn=...); the former one still answers
    if name == "learn_at_stops":
        warn_former("precontour.compensation.learn_at_stops",
                    "learn with compensate(servo, trajectory, learn=...)", kind="entry")
        from .stops import learn_at_stops

        return learn_at_stops
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
