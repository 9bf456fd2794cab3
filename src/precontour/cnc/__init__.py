"""What the real controller executes: its own trace of a program, and the program's own blocks
with corrected end points at that timing.

A controller re-plans what it is given. This stage starts from what the controller produced
for the uncompensated program (:mod:`.trace`: its servo trace, read from any format the
identification reads, or recorded from LinuxCNC run headless) and hands back the program as
written with its end points corrected for that timing (:mod:`.blocks`).
"""

from .blocks import CorrectedProgram, correct_program
from .trace import ControllerTrace, read_controller_trace, trace_from_recording

__all__ = ["ControllerTrace", "CorrectedProgram", "correct_program", "read_controller_trace",
           "trace_from_recording"]
