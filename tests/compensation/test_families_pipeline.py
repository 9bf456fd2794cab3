"""The whole pipeline on the head families and the two-tilt table: the built-in ``paper`` path
planned on the built-in head-table B-C machine, on LinuxCNC's bridge mill (head-head), on the
head-table A-C machine described as a generic chain and on LinuxCNC's A-B table dual rotary
(xyzab_tdr_kins), contour-compensated within
the limits with pid-high, and both commands run on the realistic virtual machine (discrete PID,
friction, feed-forward friction compensation); errors measured in each machine's workpiece
frame. Targets (issue: at least what the trunnion paths reach): >= 85 % of the max tip error
and >= 95 % of the mean removed. The stop at the path's end is decided by friction, so the
bound holds on every one of :data:`conftest.FRICTION_DRAWS` nanometre draws
(:func:`conftest.nanometre_draws`). Measured (5 draws; max / mean tip, max orientation):
head-table-bc 94.8 / 98.1 / 99.0 % on each; linuxcnc-bridgemill 93.2 / 97.7-97.8 / 96.0 %;
head-table-ac 94.2 / 98.1 / 97.2 %; linuxcnc-xyzab-tdr 89.8 / 96.6 / 96.8 % (zhang2013, the
same run: 88.2 / 96.7 / 97.3 %).
"""

import pytest

from conftest import nanometre_draws
from precontour.machine import load_machine
from precontour.trajectory import builtin_path
from precontour.trajectory.generate import generate_trajectory
from precontour.compensation.routes import keep_limits
from precontour.machine.servo import load_servo
from precontour.workflow import check_on_virtual_machine


@pytest.mark.parametrize("machine_name", ["head-table-bc", "linuxcnc-bridgemill", "head-table-ac",
                                          "linuxcnc-xyzab-tdr"])
def test_paper_path_compensated_on_the_head_families(machine_name):
    machine = load_machine(machine_name)
    reductions = []
    for path in nanometre_draws(builtin_path("paper")):
        planned = generate_trajectory(path, machine)
        limited = keep_limits(load_servo(machine, "pid-high"), planned)
        reference = limited.reference
        before, after = check_on_virtual_machine(reference, limited.result.trajectory.q,
                                                 machine_name, "pid-high")
        reductions.append((1 - after.tip.max() / before.tip.max(),
                           1 - after.tip.mean() / before.tip.mean(),
                           1 - after.orientation.max() / before.orientation.max()))
    worst_max = min(r[0] for r in reductions)
    worst_mean = min(r[1] for r in reductions)
    assert worst_max >= 0.85, reductions
    assert worst_mean >= 0.95, reductions
    assert min(r[2] for r in reductions) >= 0.85, reductions
