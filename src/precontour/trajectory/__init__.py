"""Trajectory generation: from a programmed tool path to time-stamped axis commands.

- :mod:`.sampled` -- :class:`Trajectory`, axis commands (and the reference tool path) sampled
  at the servo period: the object every later stage takes;
- :mod:`.pathspline` -- C3 geometric splines of the tool tip and orientation;
- :mod:`.feedplan` -- jerk-limited feed within the feed and axis limits;
- :mod:`.generate` -- :func:`generate_trajectory`: path spline + feed plan + inverse kinematics;
- :mod:`.program` -- :func:`program_trajectory`: an NC program timed as a CNC executes it;
- :mod:`.builtin_paths` -- the built-in test paths (``paper``, ``circle``, ``cone``, ``fan``).
"""

from .builtin_paths import BUILTIN_PATHS, builtin_path
from .feedplan import DEFAULT_FEED, FeedProfile, plan_feed
from .generate import DEFAULT_DWELL, TrajectorySummary, generate_trajectory, summarize
from .pathspline import PathSpline, fit_path, fit_toolpath
from .program import program_trajectory
from .sampled import Trajectory

__all__ = ["BUILTIN_PATHS", "DEFAULT_DWELL", "DEFAULT_FEED", "FeedProfile", "PathSpline",
           "Trajectory", "TrajectorySummary", "builtin_path", "fit_path", "fit_toolpath",
           "generate_trajectory", "plan_feed", "program_trajectory", "summarize"]
