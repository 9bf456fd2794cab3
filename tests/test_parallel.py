"""The jobs setting and the ordered thread map: results in order, memory bounded by the jobs,
and ``run``'s numbers the same whatever the jobs."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import servo_of
from precontour.errors import InputError
from precontour.parallel import jobs, map_ordered, program_executor, using_jobs

PROGRAM = Path(__file__).parent / "linuxcnc" / "data" / "3plus2.ngc"


def test_using_jobs_sets_and_restores_the_setting():
    before = jobs()
    with using_jobs(3):
        assert jobs() == 3
        with using_jobs(None):
            assert jobs() == 3
        with using_jobs(1):
            assert jobs() == 1
        assert jobs() == 3
    assert jobs() == before
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(InputError, match="whole number >= 1"):
            with using_jobs(bad):
                pass


def test_map_ordered_keeps_the_order_and_bounds_what_runs_ahead():
    """Tasks that end in reverse order come back in order; no more than ``workers`` results
    exist before the caller takes one (counted as tasks started minus results taken)."""
    started, taken, most = [0], [0], [0]
    lock = threading.Lock()

    def task(i):
        with lock:
            started[0] += 1
            most[0] = max(most[0], started[0] - taken[0])
        time.sleep(0.002 * (10 - i % 10))
        return i * i

    out = []
    for value in map_ordered(task, range(30), workers=3):
        out.append(value)
        with lock:
            taken[0] += 1
    assert out == [i * i for i in range(30)]
    assert most[0] <= 3 + 1   # the workers' results and the one being taken


def test_map_ordered_passes_a_task_error_to_the_caller():
    def task(i):
        if i == 4:
            raise ValueError("task 4")
        return i

    with pytest.raises(ValueError, match="task 4"):
        list(map_ordered(task, range(10), workers=2))


def test_program_executor_refuses_an_address_that_is_not_dask():
    with pytest.raises(InputError, match="dask://HOST:PORT"):
        program_executor("tcp://127.0.0.1:8786")
    with pytest.raises(InputError, match="dask://HOST:PORT"):
        program_executor("dask://")


def test_program_executor_says_when_no_dask_scheduler_answers(monkeypatch):
    """A port nobody listens on (taken from the system, then freed): one line naming the
    address, the wait and the option, within about the wait."""
    import socket
    import time

    import precontour.parallel as parallel

    pytest.importorskip("distributed", reason="the dask extra (distributed) is not installed")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    monkeypatch.setattr(parallel, "DASK_CONNECT_SECONDS", 1)
    start = time.monotonic()
    with pytest.raises(InputError, match=rf"field '--executor': no Dask scheduler answered at "
                                         rf"dask://127\.0\.0\.1:{port} within 1 s \(") as caught:
        program_executor(f"dask://127.0.0.1:{port}")
    assert "\n" not in str(caught.value)
    assert time.monotonic() - start < 30


def test_run_gives_the_same_numbers_with_one_job_and_with_two():
    """``run`` on the 3+2 program with its five draws: the written program, the simulated
    errors and every draw's block maxima are identical, bit for bit, with one job and with
    two (the draws on two threads, the kernels' chunks split in two)."""
    from precontour.workflow import run_program

    results = {}
    for n in (1, 2):
        with using_jobs(n):
            results[n] = run_program(PROGRAM, machine="zhang2013", controller="pid-high")
    one, two = results[1], results[2]
    assert one.program.text == two.program.text
    np.testing.assert_array_equal(one.simulated_after.tip, two.simulated_after.tip)
    np.testing.assert_array_equal(one.simulated_before.orientation,
                                  two.simulated_before.orientation)
    for name in ("tip_max", "orientation_max", "tip_mean"):
        np.testing.assert_array_equal(getattr(one.draws.before, name),
                                      getattr(two.draws.before, name))
        np.testing.assert_array_equal(getattr(one.draws.after, name),
                                      getattr(two.draws.after, name))
    assert one.draws.before.tip_max.shape[0] == 5


def test_a_long_program_in_pieces_is_the_same_with_one_job_and_with_two():
    """Prediction, contour errors and compensation of a program cut into pieces (the pieces
    side by side on two threads): bit for bit what one job computes, piece after piece."""
    from precontour import load_machine
    from precontour.compensation.pieces import (compensate_program, contour_errors_program,
                                                predict_program)
    from precontour.trajectory.builtin_paths import builtin_path
    from precontour.trajectory.generate import generate_trajectory

    machine = load_machine("zhang2013")
    servo = servo_of(machine, "pid-high")
    traj = generate_trajectory(builtin_path("fan"), machine)
    pieces = dict(piece_samples=traj.n_samples // 4, at_once_samples=traj.n_samples // 4)
    out = {}
    for n in (1, 2):
        with using_jobs(n):
            predicted = predict_program(servo, traj, **pieces)
            compensated = compensate_program(servo, traj, **pieces)
            errors = contour_errors_program(traj, compensated.trajectory.q,
                                            machine.kinematics, **pieces)
            out[n] = (predicted, compensated, errors)
    (p1, c1, e1), (p2, c2, e2) = out[1], out[2]
    assert p1.pieces == p2.pieces >= 3
    np.testing.assert_array_equal(p1.e, p2.e)
    np.testing.assert_array_equal(p1.contour.tip, p2.contour.tip)
    np.testing.assert_array_equal(c1.trajectory.q, c2.trajectory.q)
    np.testing.assert_array_equal(e1.tip, e2.tip)
    np.testing.assert_array_equal(e1.orientation, e2.orientation)
