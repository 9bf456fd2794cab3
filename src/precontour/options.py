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
:func:`limit_options`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np

from .defaults import (DEFAULT_FEED_SCALE_MAX, DEFAULT_FEED_SCALE_MAX_CL,
                       DEFAULT_FEED_SCALE_MIN, DEFAULT_LEARNING_PASSES, DEFAULT_MIN_SPEED,
                       FORMER_SPELLINGS_REMOVED_IN)
from .errors import InputError, is_whole_number
from .planning.tolerance import ContourTolerance
from .simulation.ensemble import MachineEnsemble

__all__ = ["LearningOptions", "LimitOptions", "ToleranceOptions", "learning_options",
           "limit_options", "with_former_spellings", "FORMER_SPELLINGS_REMOVED_IN"]


@dataclass(frozen=True)
class LearningOptions:
    """Learning against the realistic virtual machine (docs/learning.md).

    Attributes
    ----------
    passes : int
        Passes of learning (``--learn``), >= 0; 0: no learning.
    controller : str or None
        The controller the virtual machine runs when learning (``--learn-controller``; None:
        :func:`precontour.system.learning_controller` chooses).
    ensemble : MachineEnsemble or None
        The draws of the realistic virtual machine every decision is taken on (None:
        :class:`~precontour.simulation.ensemble.MachineEnsemble` (), 5 draws).
    """

    passes: int = DEFAULT_LEARNING_PASSES
    controller: str | None = None
    ensemble: MachineEnsemble | None = None

    def __post_init__(self):
        if not is_whole_number(self.passes) or self.passes < 0:
            raise InputError(f"learning passes must be a whole number >= 0, got "
                             f"{self.passes!r}", field="--learn")
        object.__setattr__(self, "passes", int(self.passes))
        if self.controller is not None and not (isinstance(self.controller, str)
                                                and self.controller):
            raise InputError(f"the learning controller must be a controller's name, got "
                             f"{self.controller!r}", field="--learn-controller")
        if self.ensemble is not None and not isinstance(self.ensemble, MachineEnsemble):
            raise InputError(f"the ensemble must be a MachineEnsemble, got "
                             f"{type(self.ensemble).__name__}", field="ensemble")

    def draws(self) -> MachineEnsemble:
        """The ensemble learning decides on (the default one where none is given)."""
        return MachineEnsemble() if self.ensemble is None else self.ensemble


@dataclass(frozen=True)
class LimitOptions:
    """Keeping the machine's axis limits (velocity, acceleration, jerk).

    Attributes
    ----------
    keep : bool
        Keep them, slowing the motion down locally and compensating again where needed
        (False: ``--ignore-limits``, the commands may break them).
    min_speed : float
        The floor of those slow-downs, a fraction of the planned speed in (0, 1]
        (``--min-speed``): where keeping a limit needs slower, the compensation there is left
        out; 1: never slowed.
    """

    keep: bool = True
    min_speed: float = DEFAULT_MIN_SPEED

    def __post_init__(self):
        if not isinstance(self.keep, (bool, np.bool_)):
            raise InputError(f"keep must be True or False, got {self.keep!r}",
                             field="--ignore-limits")
        value = self.min_speed
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
                or not (math.isfinite(value) and 0.0 < value <= 1.0):
            raise InputError(f"must be a fraction in (0, 1], got {value!r}",
                             field="--min-speed")
        object.__setattr__(self, "keep", bool(self.keep))
        object.__setattr__(self, "min_speed", float(value))


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


def learning_options(learn) -> LearningOptions:
    """``learn`` as :class:`LearningOptions`: itself, or a number of passes (0: none)."""
    if isinstance(learn, LearningOptions):
        return learn
    return LearningOptions(passes=learn)


def limit_options(limits) -> LimitOptions:
    """``limits`` as :class:`LimitOptions`: itself, or whether to keep them (True, False)."""
    if isinstance(limits, LimitOptions):
        return limits
    return LimitOptions(keep=limits)




def with_former_spellings(value, kind: type, make, name: str, **former):
    """``value`` as options of ``kind`` (itself, or ``make(value)`` of a plain value) with the
    fields given in their former spellings (``former``: field -> value, None where not given),
    each with a DeprecationWarning naming the release that removes it (pointed at the caller
    of the function that takes them). Beside an options object they are refused: the object
    holds them."""
    given = {key: v for key, v in former.items() if v is not None}
    if isinstance(value, kind):
        if given:
            raise InputError(f"give {', '.join(given)} in {name} ({kind.__name__}), not "
                             "beside it", field=next(iter(given)))
        return value
    if given:
        fields = ", ".join(f"{key}=..." for key in given)
        warnings.warn(f"{', '.join(f'{key}=' for key in given)}: former spelling, removed in "
                      f"precontour {FORMER_SPELLINGS_REMOVED_IN}; give {name}="
                      f"{kind.__name__}({fields})", DeprecationWarning, stacklevel=3)
    options = make(value)
    return replace(options, **given) if given else options
