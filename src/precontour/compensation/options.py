"""The compensation's options, as small frozen objects that check themselves.

:class:`LearningOptions`: learning against the realistic virtual machine (``--learn``,
``--learn-controller``, the ensemble of its draws); :class:`LimitOptions`: keeping the
machine's axis limits (``--ignore-limits``, ``--min-speed``). Where
:func:`~precontour.compensation.compensate` also takes a plain value (``learn=4``,
``limits=False``), it means the options object made from it (:func:`learning_options`,
:func:`limit_options`). Both are re-exported by :mod:`precontour.options`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..defaults import DEFAULT_LEARNING_PASSES, DEFAULT_MIN_SPEED
from ..errors import InputError, is_whole_number
from ..simulation.ensemble import MachineEnsemble

__all__ = ["LearningOptions", "LimitOptions", "learning_options", "limit_options"]


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
