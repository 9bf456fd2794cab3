"""The virtual machine: the axis commands run in the time domain.

- :mod:`.virtual_machine` -- :func:`simulate` / :func:`simulate_trajectory`: plant, friction,
  feed-forward friction compensation, discrete (ZOH at the servo rate) or continuous control;
- :mod:`.control_laws` -- the control laws (PID, P-PI, sliding mode), discrete and continuous.
"""

from .virtual_machine import SimulationResult, simulate, simulate_trajectory

__all__ = ["SimulationResult", "simulate", "simulate_trajectory"]
