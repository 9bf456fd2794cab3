"""block_timing, the measurement of tests/linuxcnc and scripts/measure_linuxcnc.py, on
recordings built here from a program's own blocks (no LinuxCNC needed): a recording that
executes every block on time measures on time, one with a block stretched measures it late
by the stretch, from that block on."""

from __future__ import annotations

import numpy as np
import pytest

from precontour.linuxcnc.run import Recording, block_timing, parse_run_gcode
from precontour.toolpath.writers import gcode_program

TS = 0.001


def _program():
    t = np.arange(1500) * TS
    q = np.column_stack([30 * np.sin(2 * t), 20 * np.cos(3 * t), 5 * t, 0.2 * np.sin(t),
                         np.where(t < 0.8, 0.0, 0.3 * (t - 0.8))])
    return gcode_program(t, q)


def _recording(text: str, stretch_block: int | None = None, factor: float = 1.0,
               idle: int = 40) -> Recording:
    """The planner as an ideal one: each block's end at its programmed time (block
    ``stretch_block`` takes ``factor`` times its own), straight lines between, sampled every
    servo period after ``idle`` periods at the start point."""
    start, blocks = parse_run_gcode(text)
    ends = np.vstack([start] + [b[1] for b in blocks])
    seconds = np.array([b[2] for b in blocks])
    if stretch_block is not None:
        seconds[stretch_block] *= factor
    times = np.r_[0.0, np.cumsum(seconds)]
    t = np.arange(int(times[-1] / TS) + 20) * TS
    world = np.column_stack([np.interp(t, times, ends[:, i]) for i in range(5)])
    block = np.minimum(np.searchsorted(times, t, side="right") - 1, len(blocks) - 1)
    line = np.array([b[0] for b in blocks])[block]
    world = np.vstack([np.repeat(start[None], idle, axis=0), world])
    line = np.r_[np.zeros(idle, dtype=np.int64), line]
    columns = {f"w{i}": world[:, i] for i in range(5)}
    columns.update({f"j{i}": world[:, i] for i in range(5)}, line=line,
                   motion_type=np.zeros_like(line))
    return Recording(sample=np.arange(line.size), ts=TS, joints=world, columns=columns,
                     overruns=0)


def test_blocks_on_time_measure_on_time():
    program = _program()
    timing = block_timing(program.text, _recording(program.text))
    assert timing.line.size == program.n_blocks
    assert timing.measured.sum() >= program.n_blocks - 1
    np.testing.assert_allclose(timing.late[timing.measured], 0.0, atol=1e-9)
    assert timing.late_blocks() == 0
    assert timing.duration[1] == pytest.approx(timing.duration[0], abs=1e-9)
    # the rotary flags are the blocks whose A or C word changes
    assert timing.rotary.sum() == program.rotary_blocks


def test_a_stretched_block_is_late_by_its_stretch_from_there_on():
    program = _program()
    k = program.n_blocks // 2
    timing = block_timing(program.text, _recording(program.text, k, 3.0))
    extra = 2.0 * (timing.programmed[k] - timing.programmed[k - 1])
    late = timing.late
    np.testing.assert_allclose(late[:k][timing.measured[:k]], 0.0, atol=1e-9)
    np.testing.assert_allclose(late[k:][timing.measured[k:]], extra, atol=1e-9)
    assert timing.late_blocks() == timing.measured[k:].sum()
