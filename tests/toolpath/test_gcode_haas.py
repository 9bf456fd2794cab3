"""Haas programs (G234 TCPC, G254/G255 DWO, G91 G28 then G53, inch) and tool lengths from a
tool table, read by precontour.toolpath.read_program. Expected numbers are worked by hand
from the Haas mill operator's manual's descriptions and the xyzbc-trt kinematics' documented
equation (src/precontour/machine/kinematics/xyzbc_trt.py), not from the reader."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from precontour.defaults import DEFAULT_CORNER_TOLERANCE
from precontour.errors import InputError, ProgramError
from precontour.machine.machine_file import builtin_machine_text, load_machine, parse_machine
from precontour.machine.tools import read_tool_table
from precontour.toolpath import read_program

DATA = Path(__file__).parent / "data"
INCH = 25.4
#: The test machine's rotation centre and work offsets (data/haas-umc750.toml).
CENTRE = np.array([-381.0, -254.0, -450.0])
G54 = CENTRE
G55 = np.array([-331.0, -254.0, -430.0])


@pytest.fixture(scope="module")
def umc():
    return load_machine(DATA / "haas-umc750.toml")


def write(tmp_path: Path, text: str, name: str = "prog.nc") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def tip_and_axis(machine, q, length):
    """Tool tip and orientation of machine axes q with tool length ``length``."""
    return replace(machine.kinematics, tool_offset=length).forward(np.asarray(q))


def orientation(b_deg, c_deg):
    """O = (sin b cos c, sin b sin c, cos b), the kinematics' documented orientation."""
    b, c = np.radians(b_deg), np.radians(c_deg)
    return np.array([math.sin(b) * math.cos(c), math.sin(b) * math.sin(c), math.cos(b)])


def last_of(program):
    return {line: k for k, line in enumerate(program.line)}


def test_nx_style_inch_program_with_g234_and_g53_after_g91_g28(umc):
    """data/haas_nx_umc750.nc: G20, G91 G28 Z0. then G53 G00 Z0. with G91 still on, two
    G234 H sections with their tools' lengths from the machine file's [tools]."""
    from precontour.trajectory import program_trajectory, summarize
    program = read_program(DATA / "haas_nx_umc750.nc", umc)
    assert program.notices == (
        f"{DATA / 'haas_nx_umc750.nc'}, line 7: G53 under G91: its axis words are taken as "
        "machine positions (absolute), as a Haas control moves; LinuxCNC refuses G53 under "
        "G91",)
    last = last_of(program)
    # tips (inch words, G54 at the rotation centre) with tool 1 (95.25 mm) and tool 2 (120 mm)
    expected = {15: (1, [0, 0, 0], 15, 30), 16: (1, [0.25, 0.1, -0.02], 17.5, 34),
                17: (1, [0.5, 0.2, -0.04], 20, 38), 18: (1, [0.7, 0.4, -0.04], 20, 38),
                19: (1, [0.8, 0.4, -0.04], 22, 42), 31: (2, [0.5, -0.5, 0.0], -18, -40),
                32: (2, [0.0, 0.0, -0.05], -15, -35)}
    lengths = {1: 95.25, 2: 120.0}
    for line, (tool, words, b, c) in expected.items():
        k = last[line]
        assert program.tcp_move[k]
        tip, axis = tip_and_axis(umc, program.q[k], lengths[tool])
        np.testing.assert_allclose(tip, G54 + INCH * np.array(words), atol=1e-9)
        np.testing.assert_allclose(axis, orientation(b, c), atol=1e-12)
    # the G2 arc about (0.5, 0.4) in, radius 0.2 in, in the turned work frame
    arc = np.array([tip_and_axis(umc, q, 95.25)[0] for q in program.q[program.line == 18]])
    np.testing.assert_allclose(np.hypot(*(arc[:, :2] - (G54[:2] + INCH * np.array([0.5, 0.4]))).T),
                               0.2 * INCH, atol=1e-9)
    # G91 G28 Z0. (machine zero: the file's g28) and G53 G00 Z0.: machine Z 0, X Y stay
    for line in (23, 24, 35, 36):
        assert program.q[last[line], 2] == 0.0 and not program.tcp_move[last[line]]
    np.testing.assert_allclose(program.q[last[36], :2], program.q[last[33], :2])
    np.testing.assert_allclose(program.q[last[37], 3:], [0.0, 0.0])
    # timing in inches per minute: line 16 at F60. (in/min)
    chord = INCH * math.dist([0, 0, 0], [0.25, 0.1, -0.02])
    assert program.duration[last[16]] == pytest.approx(60 * chord / (60 * INCH))
    # planned: the commands pass every programmed point within the corner tolerance
    trajectory = program_trajectory(program, umc)
    assert summarize(trajectory, umc).within_limits
    for k in range(program.n_moves):
        distance = np.linalg.norm(trajectory.q[:, :3] - program.q[k, :3], axis=1)
        nearest = int(np.argmin(distance))
        assert distance[nearest] <= DEFAULT_CORNER_TOLERANCE + 1e-9, program.line[k]


def test_fusion_style_program_with_dwo_drilling_and_tcpc(umc):
    """data/haas_fusion_umc750.nc: G254 3+2 drilling in G55 (the part zero 50 mm along +X and
    20 mm above the rotation centre) at B90 C0 and B90 C-90, then a G234 flowline."""
    program = read_program(DATA / "haas_fusion_umc750.nc", umc)
    last = last_of(program)
    # DWO: the work offset turned with the table, X Y Z along the machine axes. From the
    # kinematics' equation P = Rz(c) Ry(b) (M - r) + r (tool 0, offsets 0): the part zero,
    # d = G55 - r = (50, 0, 20), is under the spindle at M = r + Ry(-b) Rz(-c) d:
    # B90 C0 -> r + (-20, 0, 50); B90 C-90 -> r + (-20, 50, 0).
    origin_1 = CENTRE + [-20.0, 0.0, 50.0]
    origin_2 = CENTRE + [-20.0, 50.0, 0.0]
    np.testing.assert_allclose(program.q[last[20]], [*(origin_1 + [5, 5, 15]), math.pi / 2, 0],
                               atol=1e-9)
    bottoms = program.q[np.isin(program.line, [21, 22]), 2].min()
    assert bottoms == pytest.approx(origin_1[2] - 8.0)
    np.testing.assert_allclose(program.q[last[22], :2], origin_1[:2] + [-5, 5], atol=1e-9)
    # the rotary-only block under G254 turns the table, X Y Z held
    np.testing.assert_allclose(program.q[last[26]], [*program.q[last[25], :3], math.pi / 2,
                                                    -math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(program.q[last[29]], [*(origin_2 + [5, 5, -2]), math.pi / 2,
                                                    -math.pi / 2], atol=1e-9)
    assert not program.tcp_move[last[29]]
    # G255 then G234: tips in G54 with tool 1 (95.25 mm)
    for line, words, b, c in ((44, [8, 2, 0], 12, 5), (45, [6, 4, -0.5], 14, 10),
                              (47, [1, 5, -1], 16, 15)):
        tip, axis = tip_and_axis(umc, program.q[last[line]], 95.25)
        np.testing.assert_allclose(tip, G54 + words, atol=1e-9)
        np.testing.assert_allclose(axis, orientation(b, c), atol=1e-12)
    arc = np.array([tip_and_axis(umc, q, 95.25)[0] for q in program.q[program.line == 46]])
    np.testing.assert_allclose(np.hypot(*(arc[:, :2] - (G54[:2] + [4, 4])).T), 2.0, atol=1e-9)
    assert program.q[last[50], 2] == 0.0 and not program.tcp_move[last[50]]


TCP_TWO_TOOLS = """G21 G90 G54
T1 M6
G0 B10. C20.
G0 X0 Y0 Z0
G234 H1
G1 X5. Y2. Z1. F500.
G49
T2 M6
G43.4
G1 X-3. Y1. Z2.
G49
M30
"""


def test_tool_table_file_replaces_the_machine_files_lengths(umc, tmp_path):
    """A LinuxCNC tool table (--tool-table) gives tool 1 80 mm and tool 2 100 mm: the tips
    stay, the machine Z of each TCP move moves by the difference to the [tools] length along
    the tool (machine Z on a table-tilting machine); G43.4 without H takes tool 2 (T2 M6)."""
    path = write(tmp_path, TCP_TWO_TOOLS)
    table = write(tmp_path, "; LinuxCNC tool table\nT1 P1 Z80.0 D6.0 ;ball 6\n"
                            "T2 P2 Z100 D10 ;bull 10\n", "tool.tbl")
    assert dict(read_tool_table(table)) == {1: 80.0, 2: 100.0}
    by_file = read_program(path, umc)
    by_table = read_program(path, umc, tool_table=table)
    last = last_of(by_table)
    for line, old, new in ((6, 95.25, 80.0), (10, 120.0, 100.0)):
        k = last[line]
        np.testing.assert_allclose(by_table.q[k] - by_file.q[k], [0, 0, new - old, 0, 0],
                                   atol=1e-9)
        np.testing.assert_allclose(tip_and_axis(umc, by_table.q[k], new)[0],
                                   tip_and_axis(umc, by_file.q[k], old)[0], atol=1e-9)
    mapping = read_program(path, umc, tool_table={1: 80.0, 2: 100.0})
    np.testing.assert_allclose(mapping.q, by_table.q)


def test_a_tool_the_table_lacks_is_said_once_and_takes_tool_offset(umc, tmp_path):
    path = write(tmp_path, TCP_TWO_TOOLS.replace("G43.4\n", "G43.4 H7\n").replace(
        "G234 H1\n", "G234 H7\n"))
    program = read_program(path, umc, tool_table={1: 80.0})
    assert program.notices == (f"{path}, line 5: tool 7 (H7) is not in the tool table; its "
                               "length is the machine file's tool_offset (0 mm)",)
    tip, _ = umc.kinematics.forward(program.q[last_of(program)[6]])
    np.testing.assert_allclose(tip, G54 + [5, 2, 1], atol=1e-9)


def test_no_table_keeps_the_machine_files_tool_offset(tmp_path):
    """Without [tools] and --tool-table nothing changes: the kinematics' own tool_offset."""
    machine = load_machine("linuxcnc-xyzbc-trt")
    program = read_program(write(tmp_path, TCP_TWO_TOOLS), machine)
    assert not any("tool" in text for text in program.notices)
    tip, _ = machine.kinematics.forward(program.q[last_of(program)[10]])
    np.testing.assert_allclose(tip, [-3, 1, 2], atol=1e-9)


def test_g43_ends_g234_and_a_sites_g_code_switches_tcp(tmp_path):
    text = "G21 G90\nG0 X0 Y0 Z10 B20 C0\nG234 H1\nG1 X1 F100\nG43 H1\nG1 X2\nM30\n"
    machine = load_machine("linuxcnc-xyzbc-trt")
    program = read_program(write(tmp_path, text), machine)
    assert list(program.tcp_move) == [True, False]
    site = parse_machine(builtin_machine_text("linuxcnc-xyzbc-trt")
                         + '[gcode]\ntcp_on = ["G43.7"]\ntcp_off = ["G43.8"]\n')
    program = read_program(write(tmp_path, text.replace("G234 H1", "G43.7").replace(
        "G43 H1", "G43.8")), site)
    assert list(program.tcp_move) == [True, False]


def _refusal(path, machine):
    with pytest.raises(ProgramError) as info:
        read_program(path, machine)
    return info.value


@pytest.mark.parametrize("text, line, word, message", [
    ("G21 G54\nG0 X0 Y0 Z50 B0 C0\nG254\nG234 H1\n", 4, "G234",
     "G234 (tool centre point control) with G254 (dynamic work offset) on: Haas runs them one "
     "at a time; cancel G254 with G255 first"),
    ("G21 G54\nG0 X0 Y0 Z50 B0 C0\nG234 H1\nG254\n", 4, "G254",
     "G254 (dynamic work offset) in tool centre point mode (G234): Haas runs them one at a "
     "time; end TCP first"),
    ("G21 G54\nG0 X0 Y0 Z50 B0 C0\nG254\nG1 X5 B10 F100\n", 4, "B10",
     "B10 and X5 in one block under G254 (dynamic work offset, for 3+2 positioning): move the "
     "rotary axes in a block of their own, or use G234 (tool centre point control) for "
     "simultaneous motion"),
    ("G21\nT1.5 M6\n", 2, "T1.5", "tool number 'T1.5' must be a whole number >= 0"),
    ("G21\nG0 X0 Y0 Z50 B0 C0\nG234 H-1\n", 3, "H-1",
     "tool length offset 'H-1' must be a whole number >= 0"),
])
def test_haas_refusals_name_the_construct_file_and_line(umc, tmp_path, text, line, word,
                                                        message):
    path = write(tmp_path, text)
    error = _refusal(path, umc)
    assert (error.row, error.field) == (line, word)
    assert str(error) == f"{path}, line {line}, word {word!r}: {message}"


@pytest.mark.parametrize("text, line, field, message", [
    ("T1 P1 Z50\nT1 P2 Z60\n", 2, "T", "tool 1 is given twice"),
    ("T1 P1 Z50 K3\n", 1, "K3", "word 'K3' is no tool table word (T P X Y Z A B C U V W D I J "
                                "Q, each once)"),
    ("P1 Z50\n", 1, "T", "a tool table line needs its tool number T (1 or more)"),
    ("T2 P1 Z50 junk\n", 1, "junk", "cannot read 'junk': a tool table line is T<n> P<pocket> "
                                    "Z<length> ... ;remark"),
])
def test_tool_table_errors_name_the_file_line_and_word(tmp_path, text, line, field, message):
    path = write(tmp_path, text, "tool.tbl")
    with pytest.raises(InputError) as info:
        read_tool_table(path)
    assert (info.value.row, info.value.field) == (line, field)
    assert message in str(info.value) and str(path) in str(info.value)


def test_cl_data_without_a_feed_says_the_feed_once(tmp_path, caplog):
    from precontour.trajectory.generate import unfed_notice
    from precontour.workflow import read_run_program
    path = write(tmp_path, "Px,Py,Pz,Oi,Oj,Ok\n0,0,0,0,0,1\n10,0,0,0,0,1\n", "path.csv")
    machine = load_machine("zhang2013")
    read_run_program(path, machine)
    said = [r.getMessage() for r in caplog.records]
    assert said == [f"{path}: no feed is programmed (no FEDRAT, no F column); planned at 100 "
                    "mm/s (6000 mm/min)"]
    fed = write(tmp_path, "Px,Py,Pz,Oi,Oj,Ok,F\n0,0,0,0,0,1,\n10,0,0,0,0,1,600\n", "fed.csv")
    caplog.clear()
    read_run_program(fed, machine)
    assert not caplog.records
    from precontour.trajectory import builtin_path
    assert unfed_notice(builtin_path("paper")) is None
    with pytest.raises(InputError, match=r"--tool-table applies to G-code programs only"):
        read_run_program(path, machine, tool_table=write(tmp_path, "T1 Z5\n", "t.tbl"))


def test_trajectory_command_takes_a_tool_table(tmp_path, capsys):
    """--tool-table on the command line: the written Z of the TCP move is the table's."""
    from precontour.cli import main
    from precontour.tables import read_columns
    program = write(tmp_path, TCP_TWO_TOOLS)
    table = write(tmp_path, "T1 P1 Z80\nT2 P2 Z100\n", "tool.tbl")
    machine = DATA / "haas-umc750.toml"
    assert main(["trajectory", str(program), "--machine", str(machine), "-o",
                 str(tmp_path / "a.csv")]) == 0
    assert main(["trajectory", str(program), "--machine", str(machine), "--tool-table",
                 str(table), "-o", str(tmp_path / "b.csv")]) == 0
    a, b = (read_columns(tmp_path / name, ["Z", "line"]) for name in ("a.csv", "b.csv"))
    assert re.search(r"wrote", capsys.readouterr().out)
    # where tool 1's TCP move (line 6) ends: the same tip, machine Z 95.25 - 80 mm higher
    # with the machine file's length than with the table's
    end_a, end_b = (np.flatnonzero(t["line"] == 6)[-1] for t in (a, b))
    assert a["Z"][end_a] - b["Z"][end_b] == pytest.approx(95.25 - 80.0, abs=1e-6)
