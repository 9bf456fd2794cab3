"""LinuxCNC itself in the test suite (imported by the tests of this folder; not a conftest.py,
whose module name ``conftest`` would shadow tests/conftest.py for ``from conftest import``): fixtures that write configurations with
``precontour linuxcnc-config``'s library function and the outputs of ``run`` to run on it.

Every test here needs LinuxCNC 2.9 (Debian: ``apt-get install linuxcnc-uspace``) and is
skipped, with the reason, where it cannot run (not installed; as root, no unprivileged user
``lcnc`` or ``$PRECONTOUR_LINUXCNC_USER`` to run it as; another LinuxCNC running).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from precontour import load_machine
from precontour.linuxcnc.config import write_linuxcnc_config
from precontour.linuxcnc.run import linuxcnc_unavailable
from precontour.trajectory.builtin_paths import builtin_path
from precontour.workflow import RunOutputs, run_program, write_run_outputs

DATA = Path(__file__).parent / "data"
#: LinuxCNC's trunnion demo programs, installed with linuxcnc-uspace.
DEMOS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
             "table-rotary-tilting/demos")


@pytest.fixture(scope="session")
def lcnc():
    why = linuxcnc_unavailable()
    if why:
        pytest.skip(f"needs LinuxCNC: {why}")


@pytest.fixture(scope="session")
def config(lcnc, tmp_path_factory):
    """config(machine_name) -> a configuration folder written once per session."""
    folders = {}

    def make(name: str) -> Path:
        if name not in folders:
            folder = tmp_path_factory.mktemp("lcnc-config") / name
            write_linuxcnc_config(load_machine(name), folder)
            folders[name] = folder
        return folders[name]

    return make


@dataclass(frozen=True)
class RunFiles:
    program: Path
    stream: Path
    commands: Path
    result: object


def _run(source: Path, out: Path, machine: str, controller: str) -> RunFiles:
    outputs = RunOutputs(program=out / "comp.ngc", stream=out / "comp.txt",
                         commands=out / "comp.csv")
    result = run_program(source, outputs, machine=machine, controller=controller)
    write_run_outputs(result, outputs, [source])
    return RunFiles(outputs.program, outputs.stream, outputs.commands, result)


@pytest.fixture(scope="session")
def paper_run(lcnc, tmp_path_factory) -> RunFiles:
    """``run`` on the built-in paper path as CL data, zhang2013, pid-high (2.8 s)."""
    out = tmp_path_factory.mktemp("paper")
    path = builtin_path("paper")
    source = out / "paper.csv"
    np.savetxt(source, np.column_stack([path.P, path.O]), delimiter=",",
               header="Px,Py,Pz,Oi,Oj,Ok", comments="", fmt="%.9f")
    return _run(source, out, "zhang2013", "pid-high")


@pytest.fixture(scope="session")
def threeplus2_run(lcnc, tmp_path_factory) -> RunFiles:
    """``run`` on tests/linuxcnc/data/3plus2.ngc (3+2 with arcs), zhang2013, pid-high."""
    return _run(DATA / "3plus2.ngc", tmp_path_factory.mktemp("3plus2"), "zhang2013",
                "pid-high")
