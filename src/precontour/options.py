"""The options of the library's jobs, as small frozen objects that check themselves.

A job takes its knobs grouped by what they are about, each group one object checked when it
is made (``__post_init__``), with the one-line :class:`~precontour.errors.InputError` the
command line gives, named by the command line's option:

    compensate(servo, traj, learn=LearningOptions(passes=4, controller="pid-low"),
               limits=LimitOptions(min_speed=0.5))
    run_program(program, machine=..., controller=..., learn=2,
                contour_tolerance=ToleranceOptions(ContourTolerance.in_um(10),
                                                   feed_scale_min=0.2))

:class:`LearningOptions`: learning against the realistic virtual machine (``--learn``,
``--learn-controller``, the ensemble of its draws); :class:`LimitOptions`: keeping the
machine's axis limits (``--ignore-limits``, ``--min-speed``); :class:`ToleranceOptions`: the
fastest feed within a contour-error tolerance (``run --tolerance``, ``--feed-scale-max``,
``--feed-scale-min``, ``--write-anyway``). Where a job also takes a plain value (``learn=4``,
``limits=False``), it means the options object made from it (:func:`learning_options`,
:func:`limit_options`). The first two are the compensation's own
(:mod:`precontour.compensation.options`), gathered here with the rest.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .compensation.options import (LearningOptions, LimitOptions, learning_options,
                                   limit_options)
from .defaults import (DEFAULT_FEED_SCALE_MAX, DEFAULT_FEED_SCALE_MAX_CL,
                       DEFAULT_FEED_SCALE_MIN, FORMER_SPELLINGS_REMOVED_IN)
from .errors import InputError, with_former_spellings
from .planning.tolerance import ContourTolerance

__all__ = ["LearningOptions", "LimitOptions", "ToleranceOptions", "learning_options",
           "limit_options", "with_former_spellings", "FORMER_SPELLINGS_REMOVED_IN"]


@dataclass(frozen=True)
class ToleranceOptions:
    """The fastest feed whose compensated contour errors keep a tolerance on the realistic
    virtual machine (``run --tolerance``; :func:`~precontour.planning.feed_within_tolerance`).

    Attributes
    ----------
    tolerance : ContourTolerance or None
        Tool tip (mm) and optionally orientation (rad) (``--tolerance``, given in um and mrad:
        :meth:`ContourTolerance.in_um <precontour.planning.ContourTolerance.in_um>`); None:
        no search, and then the feed scales must keep their defaults.
    feed_scale_max : float or None
        The highest feed, a multiple of the programmed feed (``--feed-scale-max``), > 0;
        None: by the program's format (:meth:`for_format`): 1 for an NC program
        (:data:`~precontour.defaults.DEFAULT_FEED_SCALE_MAX`), 2 for CL data
        (:data:`~precontour.defaults.DEFAULT_FEED_SCALE_MAX_CL`).
    feed_scale_min : float
        The lowest feed, a fraction of the programmed feed (``--feed-scale-min``), in
        (0, ``feed_scale_max``].
    write_anyway : bool
        Give the result even where the tolerance is not met (``--write-anyway``; otherwise
        :class:`~precontour.errors.ToleranceError`).
    """

    tolerance: ContourTolerance | None = None
    feed_scale_max: float | None = None
    feed_scale_min: float = DEFAULT_FEED_SCALE_MIN
    write_anyway: bool = False

    def __post_init__(self):
        if self.tolerance is not None and not isinstance(self.tolerance, ContourTolerance):
            raise InputError(f"the tolerance must be a ContourTolerance, got "
                             f"{type(self.tolerance).__name__}", field="--tolerance")
        for name in ("--feed-scale-max", "--feed-scale-min"):
            value = getattr(self, name[2:].replace("-", "_"))
            if value is None and name == "--feed-scale-max":
                continue
            if not (isinstance(value, (int, float, np.floating)) and not isinstance(value, bool)
                    and np.isfinite(value) and value > 0):
                raise InputError(f"must be positive and finite, got {value!r}", field=name)
        if self.tolerance is None:
            if self.feed_scale_max not in (None, 1.0) \
                    or self.feed_scale_min != DEFAULT_FEED_SCALE_MIN:
                raise InputError("--feed-scale-max and --feed-scale-min apply with "
                                 "--tolerance only", field="--feed-scale-max")
        elif self.feed_scale_max is not None and self.feed_scale_min > self.feed_scale_max:
            raise InputError(f"the lowest feed scale {self.feed_scale_min:g} is above the "
                             f"highest {self.feed_scale_max:g}", field="--feed-scale-min")

    def for_format(self, format: str) -> "ToleranceOptions":
        """These options with the highest feed scale decided for a program of ``format``
        (``"gcode"`` for an NC program, else CL data) where it was left to the format."""
        if self.feed_scale_max is not None:
            return self
        cl = format != "gcode" and self.tolerance is not None
        return replace(self, feed_scale_max=DEFAULT_FEED_SCALE_MAX_CL if cl
                       else DEFAULT_FEED_SCALE_MAX)

    @property
    def search(self) -> bool:
        """Whether there is a tolerance to search the feed for."""
        return self.tolerance is not None
