"""Planning against the virtual machine: the fastest motion within a contour-error tolerance.

The stage after compensation and simulation: it retimes a planned trajectory locally
(:mod:`precontour.trajectory.retime`), compensates it within the axis limits
(:mod:`precontour.compensation.within_limits`) and measures it on the realistic virtual
machine (:mod:`precontour.simulation`), until the contour errors keep a tolerance.
"""

from .tolerance import (ContourTolerance, FeedSearch, FeedWithinTolerance, ToleranceMiss,
                        feed_within_tolerance, search_feed)

__all__ = ["ContourTolerance", "FeedSearch", "FeedWithinTolerance", "ToleranceMiss",
           "feed_within_tolerance", "search_feed"]
