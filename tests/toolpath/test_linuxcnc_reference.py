"""The G-code reader against LinuxCNC's own interpreter (see lcnc_compare.py).

Every program of the test data and of LinuxCNC's installed examples (its ``ncfiles`` and the
five-axis ``table-rotary-tilting`` demos: real CAM programs, see data/README.md) is read by
precontour. Each it accepts is run through LinuxCNC 2.9's interpreter too, and its
programmed moves -- end points, arc centres, planes and turns, canonical feed rates (F in
G94, LinuxCNC's length x F in G93), dwells, source lines -- must agree with LinuxCNC's
canonical STRAIGHT_TRAVERSE / STRAIGHT_FEED / ARC_FEED to 1e-6 mm; ``rs274``'s printout of
the unchanged program must agree with them to its 4 decimals. Each it refuses must say why
with a reason on the list below (a construct precontour does not read, on purpose).

Skipped, with the reason, where LinuxCNC is not installed.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest

from precontour.errors import PrecontourError
from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_program


from lcnc_compare import (DATA, DEMOS, NCFILES, NOT_LINUXCNC, canonical_moves, compare, linuxcnc_missing,
                          program_key as _key, program_machine as _machine, programs,
                          remap_ini, rs274_moves)

MISSING = linuxcnc_missing()

#: Why precontour refuses a LinuxCNC example (by its path in ncfiles, or demos/...): the
#: construct, on purpose not read.
REFUSED = {
    "b-index.ngc": r"B = 90 deg is outside the tilt axis's travel",       # the machine's limit
    "cone.ngc": r"unsupported word 'W100'",                               # a U V W machine
    "comp-g1.ngc": r"cutter radius compensation", "comp.ngc": r"cutter radius compensation",
    "comp311.ngc": r"cutter radius compensation", "comp311_2.ngc": r"cutter radius",
    "g76.ngc": r"cutter radius compensation", "lathe-g76.ngc": r"cutter radius",
    "lathecomp.ngc": r"cutter radius compensation", "mmount.ngc": r"cutter radius",
    "useful-subroutines.ngc": r"cutter radius compensation",
    "gmoccapy_2_tools_with_cutter_radius_compensation.ngc": r"cutter radius compensation",
    "gridprobe.ngc": r"unsupported G code G38.2", "smartprobe.ngc": r"G38.5",
    "tool-length-probe.ngc": r"G38.2",                                    # probing
    "lathe_g70_71_demo.ngc": r"G71.1", "lathe_g7x_face_boring.ngc": r"G72",
    "lathe_g7x_quadrants.ngc": r"G70", "lathe_pawn.ngc": r"G8",           # lathe cycles
    "systems.ngc": r"unsupported G code G5.1",                            # splines
    "threading.ngc": r"G33\) is not supported",                           # spindle-synchronized
    "nestedcall.ngc": r"after O<G20SUB> call only values",                # LinuxCNC refuses too
    # the program relies on where the machine stands when it starts
    "toplevel.ngc": r"incremental \(G91\) move of axis X before its position is known",
    "x-trim.ngc": r"G92 sets axis X relative to its position, which is not known yet",
    # subroutines in other files (LinuxCNC's SUBROUTINE_PATH)
    "demos/xyzac_switchkins.ngc": r"o<xyzac_switchkins_sub> is not defined in this file",
    "demos/xyzbc_switchkins.ngc": r"o<xyzbc_switchkins_sub> is not defined in this file",
}
#: Refusals for whole groups of examples.
REFUSED_PATTERNS = (
    r"no motion: no move after",            # subroutine libraries (a definition, no moves)
    r"reads a HAL pin of a running LinuxCNC",   # plasmac's #<_hal[...]>
)

PROGRAMS = programs()


@pytest.fixture(scope="module")
def remaps():
    with tempfile.TemporaryDirectory() as folder:
        yield remap_ini(Path(folder))


def test_linuxcnc_examples_are_installed():
    if not NCFILES.is_dir() or not DEMOS.is_dir():
        pytest.skip("LinuxCNC's example programs are not installed (/usr/share/linuxcnc/"
                    "ncfiles, /usr/share/doc/linuxcnc/examples)")
    assert len([p for p in PROGRAMS if NCFILES in p.parents]) > 100


@pytest.mark.parametrize("path", PROGRAMS, ids=_key)
def test_programs_agree_with_linuxcnc(path, remaps):
    machine = _machine(path)
    try:
        program = read_program(path, machine)
    except PrecontourError as exc:
        reason = str(exc)
        expected = REFUSED.get(_key(path))
        if expected is not None:
            assert re.search(expected, reason), reason
        else:
            assert path.parent != DATA, f"a test program is refused: {reason}"
            assert any(re.search(p, reason) for p in REFUSED_PATTERNS), (
                f"refused for a reason not on the list: {reason}")
        return
    assert _key(path) not in REFUSED, f"{_key(path)} is accepted now: update REFUSED"
    if MISSING:
        pytest.skip(MISSING)
    if _key(path) in NOT_LINUXCNC:
        pytest.skip(NOT_LINUXCNC[_key(path)])
    reference = canonical_moves(path, remaps)
    assert reference["error"] is None, (f"LinuxCNC stops at line {reference['error_line']}: "
                                        f"{reference['error']}")
    result = compare(program, machine, reference, rs274_moves(path, remaps))
    assert result.n_moves > 0
    assert result.end <= 1e-6 and result.centre <= 1e-6 and result.rate <= 1e-9


def test_random_expressions_agree_with_linuxcnc(tmp_path, remaps):
    """Expressions LinuxCNC's interpreter and precontour's evaluate alike: operators at every
    precedence level, unary minus, the functions, parameters."""
    if MISSING:
        pytest.skip(MISSING)
    rng = np.random.default_rng(20)
    ops = ["+", "-", "*", "/", "**", "MOD", "EQ", "NE", "GT", "GE", "LT", "LE", "AND", "OR",
           "XOR"]
    functions = ["ABS", "COS", "SIN", "FIX", "FUP", "ROUND", "EXP"]

    def operand(depth):
        choice = rng.integers(5 if depth < 3 else 2)
        if choice == 0:
            return f"{rng.uniform(-4, 4):.3f}"
        if choice == 1:
            return f"#{rng.integers(1, 4)}"
        if choice == 2:
            return f"[{expression(depth + 1)}]"
        if choice == 3:
            return f"{rng.choice(functions)}[{expression(depth + 1)}]"
        return f"-{operand(depth + 1)}"

    def expression(depth=0):
        text = operand(depth)
        for _ in range(rng.integers(0, 3)):
            op = rng.choice(ops)
            right = operand(depth)
            if op in ("/", "MOD"):
                right = f"[ABS[{right}] + 0.5]"       # no division by zero
            if op == "**":
                text, right = f"ABS[{text}]", f"[FIX[{right}] MOD 3]"   # real, bounded
            text = f"{text} {op} {right}"
        return text

    lines = ["G21 G90 G94", "#1 = 1.5 #2 = -2.25 #3 = 0.75", "G0 X0 Y0 Z0 A0 C0"]
    while len(lines) < 303:
        # bounded, so that no move leaves the travel: the value through ATAN; LinuxCNC
        # reads lines of up to 256 characters
        line = f"G1 X[ATAN[{expression()}]/[1]] F600"
        if len(line) < 200:
            lines.append(line)
    path = tmp_path / "expressions.ngc"
    path.write_text("\n".join(lines) + "\nM2\n")
    machine = load_machine("linuxcnc-xyzac-trt")
    program = read_program(path, machine)
    reference = canonical_moves(path, remaps)
    assert reference["error"] is None, reference["error"]
    result = compare(program, machine, reference, rs274_moves(path, remaps))
    assert result.n_moves == 300 and result.end <= 1e-9
