"""The virtual machine: the axis commands run in the time domain.

- :mod:`.virtual_machine` -- :func:`simulate` / :func:`simulate_trajectory`: plant, friction,
  feed-forward friction compensation, discrete (ZOH at the servo rate) or continuous control;
- :mod:`.control_laws` -- the control laws (PID, P-PI, sliding mode), discrete and continuous;
- :mod:`.ensemble` -- :class:`MachineEnsemble`, draws of the realistic machine (friction, J, B,
  encoder), and :func:`ensemble_actual`, the model that runs them side by side.
"""

from .ensemble import MachineEnsemble, ensemble_actual
from .virtual_machine import SimulationResult, simulate, simulate_draws, simulate_trajectory

__all__ = ["MachineEnsemble", "SimulationResult", "ensemble_actual", "simulate",
           "simulate_draws", "simulate_trajectory"]
