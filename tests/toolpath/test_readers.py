"""Tests of the tool-path readers: CL CSV, APT CL data, G-code, and the dispatcher."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from precontour.errors import InputError, ToolPathError
from precontour.machine.machine_file import load_machine
from precontour.toolpath import (EXTENSIONS, ToolPath, read_apt, read_apt_report, read_clcsv,
                                 read_clcsv_report, read_gcode, read_gcode_report,
                                 read_toolpath, read_toolpath_report, toolpath_format)

DATA = Path(__file__).parent / "data"
INCH = 25.4


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def quiet(func, *args, **kwargs):
    """Call a reader, ignoring Python warnings (its 7-digit orientations are normalized with a
    notice through logging, not a warning)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return func(*args, **kwargs)


def unit_rows(n, rng):
    """A smooth path of n points with orientations within 40 deg of z."""
    s = np.linspace(0.0, 1.0, n)
    P = np.column_stack([50 * s, 20 * np.sin(3 * s), 10 - 5 * s]) + rng.normal(0, 1e-3, (n, 3))
    tilt = np.radians(40) * np.sin(2 * s + 0.3)
    turn = 4.0 * s
    O = np.column_stack([np.sin(tilt) * np.sin(turn), np.sin(tilt) * np.cos(turn), np.cos(tilt)])
    return P, O


# --------------------------------------------------------------------------- CL CSV


def test_clcsv_fixture_values_feeds_and_duplicates(caplog):
    report = read_clcsv_report(DATA / "blade_finish.csv")
    assert "normalized 5 orientation vectors" in caplog.text
    tp = report.toolpath
    assert isinstance(tp, ToolPath) and tp.n_points == 5
    np.testing.assert_allclose(tp.P[:, 0], [10.0, 12.5, 15.0, 17.5, 20.0])
    np.testing.assert_allclose(tp.O[3], [0.5, 0.0, np.sqrt(3) / 2], atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(tp.O, axis=1), 1.0, atol=1e-15)
    # empty first F -> NaN; 1200 and 900 mm/min -> 20 and 15 mm/s
    np.testing.assert_array_equal(tp.feed, [np.nan, 20.0, 20.0, 15.0, 15.0])
    assert report.n_read == 6 and report.n_duplicates == 1
    np.testing.assert_array_equal(report.lines, [2, 3, 5, 6, 7])  # line 4 repeated line 3
    assert not report.rapid.any() and tp.source.endswith("blade_finish.csv")


def test_clcsv_feed_units_mm_per_s(tmp_path):
    path = write(tmp_path, "a.csv", "Px,Py,Pz,Oi,Oj,Ok,F\n0,0,0,0,0,1,5\n1,0,0,0,0,1,7.5\n")
    np.testing.assert_array_equal(read_clcsv(path, feed_units="mm/s").feed, [5.0, 7.5])
    np.testing.assert_allclose(read_clcsv(path).feed, [5 / 60, 7.5 / 60])


def test_clcsv_column_order_case_spacing_blank_lines_and_no_feed(tmp_path):
    text = ("\n  ok , OI,oj, tool, pz ,PY,px\n"
            "1, 0,0, T1 ,3, 2, 1\n"
            "\n"
            "0.8,0.6 , 0 ,T1,  6,5,4\n")
    report = read_clcsv_report(write(tmp_path, "b.csv", text))
    np.testing.assert_array_equal(report.toolpath.P, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(report.toolpath.O, [[0, 0, 1], [0.6, 0, 0.8]])
    assert np.isnan(report.toolpath.feed).all()
    np.testing.assert_array_equal(report.lines, [3, 5])


def test_clcsv_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    P, O = unit_rows(200, rng)
    feed = rng.uniform(100, 3000, 200)  # mm/min
    path = tmp_path / "rt.csv"
    np.savetxt(path, np.column_stack([np.arange(200), P, O, feed]), delimiter=",",
               fmt="%.17g", header="id,Px,Py,Pz,Oi,Oj,Ok,F", comments="")
    tp = read_clcsv(path)
    np.testing.assert_allclose(tp.P, P, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tp.O, O, rtol=0, atol=1e-15)
    np.testing.assert_allclose(tp.feed, feed / 60, rtol=1e-15)


HEADER = "Px,Py,Pz,Oi,Oj,Ok,F\n"


@pytest.mark.parametrize("text, match", [
    ("", r"empty file \(no header row\)"),
    ("\n\n", r"empty file"),
    (HEADER, r"no data rows after the header"),
    ("Px,Py,Pz,Oi,Ok\n1,2,3,0,1\n", r"row 1: header lacks column\(s\) Oj"),
    ("Px,Py,Pz,Oi,Oj,Ok,px\n", r"row 1, field 'Px': column 'Px' appears twice"),
    (HEADER + "0,0,0,0,0,1,\n1,abc,0,0,0,1,\n", r"row 3, field 'Py': cannot parse number 'abc'"),
    (HEADER + "0,0,0,0,0,1,\n1,0,0,0,0,1,fast\n", r"row 3, field 'F': cannot parse number 'fast'"),
    (HEADER + "0,0,0,0,0,1,\n1,0,0,0,0\n", r"row 3: expected 7 columns as in the header, got 5"),
    (HEADER + "0,0,0,0,0,1,\n1,0,,0,0,1,\n", r"row 3, field 'Pz': missing value"),
    (HEADER + "0,0,0,0,0,1,\n\n1,0,nan,0,0,1,\n", r"row 4, field 'Pz': value is not finite"),
    (HEADER + "0,0,0,0,0,1,\n1,0,0,0,0,inf,\n", r"row 3, field 'Ok': value is not finite"),
    (HEADER + "0,0,0,0,0,1,\n1,0,0,0,0,0,\n", r"row 3, field 'O': orientation vector has zero"),
    (HEADER + "0,0,0,0,0,1,\n1,0,0,0,0.6,0.9,\n",
     r"row 3, field 'O': orientation vector is not unit length \(\|O\| = 1.08166538"),
    (HEADER + "0,0,0,0,0,1,\n1,0,0,0,0,1,-5\n", r"row 3, field 'F': feed must be positive"),
    (HEADER + "0,0,0,0,0,1,\n", r"row 2: fewer than 2 distinct points \(1 read, 0"),
    (HEADER + "5,0,0,0,0,1,\n5,0,0,0,0,1,\n5,0,0,0,0,1,\n",
     r"row 2: fewer than 2 distinct points \(3 read, 2 consecutive duplicates dropped\)"),
    (HEADER + "0,0,0,0,0,1,\n1,0,0,0.8,0,0.6,\n2,0,0,-0.8,0,0.6,\n",
     r"row 4, field 'O': tool orientation turns by 106.3 deg \(more than 90\) in one move "
     r"from line 3"),
])
def test_clcsv_errors(tmp_path, text, match):
    path = write(tmp_path, "bad.csv", text)
    with pytest.raises(ToolPathError, match=match) as info:
        read_clcsv(path)
    assert str(info.value).startswith(str(path))


def test_clcsv_missing_file_and_bad_feed_units(tmp_path):
    with pytest.raises(ToolPathError, match=r"nothere.csv: no such tool-path file"):
        read_clcsv(tmp_path / "nothere.csv")
    path = write(tmp_path, "a.csv", HEADER + "0,0,0,0,0,1,1\n1,0,0,0,0,1,1\n")
    with pytest.raises(InputError, match=r"field 'feed_units': unknown feed unit 'ipm'"):
        read_clcsv(path, feed_units="ipm")


def test_clcsv_normalizes_small_deviation_with_one_notice(tmp_path, caplog):
    path = write(tmp_path, "n.csv", HEADER + "0,0,0,0,0,1.0000005,\n1,0,0,0,0,1,\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tp = read_clcsv(path)
    assert len(caplog.records) == 1
    assert re.search(r"n.csv: normalized 1 orientation vectors with \|O\| off by up to 5e-07",
                     caplog.text)
    np.testing.assert_array_equal(tp.O, [[0, 0, 1], [0, 0, 1]])


# --------------------------------------------------------------------------- APT


def test_apt_fixture(caplog):
    report = read_apt_report(DATA / "blade_finish.cls")
    assert "normalized" in caplog.text
    tp = report.toolpath
    np.testing.assert_array_equal(tp.P[:, 2], [40.0, 20.0, 19.5, 19.0, 18.5, 18.0, 60.0])
    # GOTO/x,y,z on line 17 keeps the orientation of line 14; line 18 repeats it (dropped)
    np.testing.assert_array_equal(tp.O[1], [0.0, 0.0, 1.0])
    assert report.n_read == 8 and report.n_duplicates == 1
    # the continued GOTO starts on line 22 and ends on line 23
    np.testing.assert_array_equal(report.lines, [14, 17, 21, 22, 25, 26, 29])
    np.testing.assert_allclose(tp.O[3], [0.3420201, 0, 0.9396926], atol=1e-7)
    np.testing.assert_array_equal(report.rapid, [1, 0, 0, 0, 0, 0, 1])
    # RAPID applies to one move; FEDRAT/MMPM,1200 = 20 mm/s, FEDRAT/ 900.0, MMPM = 15 mm/s
    np.testing.assert_array_equal(tp.feed, [np.nan, 20, 20, 20, 15, 15, np.nan])
    assert dict(report.skipped) == {"TOOL": 1, "TLDATA": 1, "MSYS": 1, "PARTNO": 1,
                                    "MULTAX": 1, "LOADTL": 1, "SPINDL": 1, "PAINT": 4,
                                    "COOLNT": 2, "END-OF-PATH": 1, "FINI": 1}
    assert report.n_skipped == 15 and report.format == "apt"


APT_TAIL = "GOTO/0,0,0,0,0,1\nGOTO/1,0,0,0,0,1\n"


@pytest.mark.parametrize("fedrat, feed_units, expected", [
    ("FEDRAT/ 600.0", "mm/min", 10.0),
    ("FEDRAT/ 6.0", "mm/s", 6.0),
    ("FEDRAT/MMPM,600", "mm/s", 10.0),
    ("fedrat / 600 , mmpm", "mm/min", 10.0),
    ("FEDRAT/IPM,30", "mm/min", 30 * INCH / 60),
])
def test_apt_fedrat_forms(tmp_path, fedrat, feed_units, expected):
    path = write(tmp_path, "f.apt", fedrat + "\n" + APT_TAIL)
    feed = read_apt(path, feed_units=feed_units).feed
    np.testing.assert_allclose(feed, [expected, expected], rtol=1e-15)


def test_apt_units_inches_and_default_orientation(tmp_path):
    text = ("GOTO/1,2,3\n"            # no orientation yet: (0, 0, 1)
            "UNITS/INCHES\nFEDRAT/10\n"
            "GOTO/1,0,0,0.6,0,0.8\n"
            "GOTO/2,0,0\n"            # keeps (0.6, 0, 0.8)
            "UNITS/MM\nFEDRAT/MMPM,600\nGOTO/3,0,0,0,0.6,0.8\n")
    tp = read_apt(write(tmp_path, "u.apt", text))
    np.testing.assert_allclose(tp.P, [[1, 2, 3], [INCH, 0, 0], [2 * INCH, 0, 0], [3, 0, 0]])
    np.testing.assert_array_equal(tp.O, [[0, 0, 1], [0.6, 0, 0.8], [0.6, 0, 0.8],
                                         [0, 0.6, 0.8]])
    # bare FEDRAT under inches: in/min
    np.testing.assert_allclose(tp.feed, [np.nan, 10 * INCH / 60, 10 * INCH / 60, 10.0])


def test_apt_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    P, O = unit_rows(300, rng)
    lines = ["PARTNO ROUND TRIP", "MULTAX", "FEDRAT/MMPM,1500"]
    lines += [f"GOTO/{p[0]:.17g},{p[1]:.17g},{p[2]:.17g},$\n  {o[0]:.17g},{o[1]:.17g},{o[2]:.17g}"
              for p, o in zip(P, O)]
    report = read_apt_report(write(tmp_path, "rt.apt", "\n".join(lines) + "\nFINI\n"))
    np.testing.assert_array_equal(report.toolpath.P, P)
    np.testing.assert_allclose(report.toolpath.O, O, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(report.lines, 4 + 2 * np.arange(300))
    assert np.all(report.toolpath.feed == 25.0)


@pytest.mark.parametrize("text, match", [
    ("", r"no motion \(no GOTO statement\)"),
    ("$$ only a comment\nPARTNO X\nFINI\n", r"no motion \(no GOTO statement\)"),
    ("GOTO/0,0,0\nGOTO/1,2.5.1,0\n", r"row 2, field 'y': cannot parse number '2.5.1'"),
    ("GOTO/0,0,0\nGOTO/1,0,0,0,0,1,\n", r"row 2, field 'GOTO': GOTO needs 3 \(x,y,z\) or 6"),
    ("GOTO/0,0,0\nGOTO/1,0,0,0\n", r"row 2, field 'GOTO': .* got 4"),
    ("GOTO/0,0,0\nGOTO/1,,0\n", r"row 2, field 'y': cannot parse number ''"),
    ("GOTO/0,0,0\nGOTO/1,0,0,0,,1\n", r"row 2, field 'j': cannot parse number ''"),
    ("GOTO/0,0,0\nFEDRAT/MMPR,0.1\nGOTO/1,0,0\n", r"row 2, field 'FEDRAT': feed per revolution"),
    ("FEDRAT/FAST\nGOTO/1,0,0\n", r"row 1, field 'FEDRAT': cannot read FEDRAT/FAST"),
    ("FEDRAT/MMPS,5\nGOTO/1,0,0\n", r"row 1, field 'FEDRAT': unknown feed unit 'MMPS'"),
    ("FEDRAT/0\nGOTO/1,0,0\n", r"row 1, field 'FEDRAT': feed must be positive"),
    ("UNITS/FEET\n", r"row 1, field 'UNITS': unknown UNITS/FEET"),
    ("GOTO/0,0,0\nCIRCLE/0,0,0,0,0,1,5\nGOTO/5,5,0\n", r"row 2, field 'CIRCLE': circular"),
    ("CYCLE/DRILL,5,MMPM,100\nGOTO/0,0,0\n", r"row 1, field 'CYCLE': canned cycles"),
    ("GOTO/0,0,0\nGOTO/1,0,0,$\n", r"row 2: continuation '\$' at the end of the file"),
    ("GOTO/0,0,0\nGOTO/1,0,nan\n", r"row 2, field 'Pz': value is not finite"),
    ("GOTO/0,0,0\nGOTO/1,0,0,0,0,0\n", r"row 2, field 'O': orientation vector has zero"),
    ("GOTO/0,0,0\nGOTO/1,0,0,0,0,2\n", r"row 2, field 'O': .*not unit length \(\|O\| = 2\b"),
    ("$$ x\nGOTO/0,0,0\nGOTO/0,0,0,0,0,1\n", r"row 2: fewer than 2 distinct points \(2 read, 1"),
    ("GOTO/0,0,0,0,0.8,0.6\nGOTO/1,0,0\n$$ flip\nGOTO/2,0,0,0,-0.8,0.6\n",
     r"row 4, field 'O': tool orientation turns by 106.3 deg .* from line 2"),
])
def test_apt_errors(tmp_path, text, match):
    path = write(tmp_path, "bad.apt", text)
    with pytest.raises(ToolPathError, match=match) as info:
        read_apt(path)
    assert str(info.value).startswith(str(path))


def test_apt_text_statement_ending_in_dollar_is_not_a_continuation(tmp_path):
    text = "PPRINT PRICE IN $\nGOTO/0,0,0\nPARTNO COST $\nGOTO/1,0,0\n"
    report = read_apt_report(write(tmp_path, "t.apt", text))
    np.testing.assert_array_equal(report.lines, [2, 4])
    assert dict(report.skipped) == {"PPRINT": 1, "PARTNO": 1}


# --------------------------------------------------------------------------- G-code


def test_gcode_fixture(machine):
    report = read_gcode_report(DATA / "blade_finish.nc", machine)
    deg = np.radians
    expected_q = [[0, 0, 150, 0, 0], [0, 0, 120, 0, 0], [0, 0, 100, 0, 0],
                  [10.5, -2.25, 100, 0, 0], [10.5, -2.25, 100, deg(5), deg(10)],
                  [12.75, -1.5, 99.5, deg(10), deg(20)], [12.75, -0.75, 99.5, deg(10), deg(20)],
                  [15, -0.75, 99.5, deg(15), deg(30)], [15, -0.75, 150, deg(15), deg(30)]]
    np.testing.assert_allclose(report.axes, expected_q, rtol=0, atol=1e-14)
    P, O = machine.kinematics.forward(np.asarray(expected_q))
    np.testing.assert_allclose(report.toolpath.P, P, rtol=0, atol=1e-12)
    np.testing.assert_allclose(report.toolpath.O, O, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(report.lines, [7, 8, 9, 10, 11, 12, 14, 15, 17])
    np.testing.assert_array_equal(report.rapid, [1, 1, 0, 0, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(report.toolpath.feed,
                                  [np.nan, np.nan, 10, 10, 20, 20, 20, 20, np.nan])
    assert report.n_duplicates == 1  # N120 repeats N110
    assert report.skipped["/"] == 1 and report.skipped["M30"] == 1
    assert report.skipped["G43"] == 1 and report.skipped["S"] == 1


def test_gcode_block_delete_off(machine, tmp_path):
    text = "G0 X0 Y0 Z0\n/G1 X5 F100\nG1 X1 F100\n"
    path = write(tmp_path, "bd.ngc", text)
    assert read_gcode(path, machine).n_points == 2
    report = read_gcode_report(path, machine, block_delete=False)
    np.testing.assert_array_equal(report.axes[:, 0], [0, 5, 1])


def test_gcode_round_trip_against_forward_kinematics(machine, tmp_path):
    rng = np.random.default_rng(3)
    n = 400
    s = np.linspace(0, 1, n)
    q = np.column_stack([80 * s - 40, 30 * np.sin(4 * s), 20 * s + rng.normal(0, 0.01, n),
                         np.radians(35 * np.sin(3 * s)), np.radians(-90 + 400 * s)])
    deg = np.degrees(q[:, 3:])
    lines = ["%", "O0042 (ROUND TRIP)", "G90 G21 G94"]
    for k in range(n):
        lines.append(f"N{10 * k + 10} G1 X{q[k, 0]:.15f} Y{q[k, 1]:.15f} Z{q[k, 2]:.15f} "
                     f"A{deg[k, 0]:.15f} C{deg[k, 1]:.15f} F{1000 + k}")
    lines += ["M30", "%"]
    report = read_gcode_report(write(tmp_path, "rt.nc", "\n".join(lines)), machine)
    P, O = machine.kinematics.forward(q)
    np.testing.assert_allclose(report.axes, q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(report.toolpath.P, P, rtol=0, atol=1e-9)
    np.testing.assert_allclose(report.toolpath.O, O, rtol=0, atol=1e-9)
    np.testing.assert_allclose(report.toolpath.feed, (1000 + np.arange(n)) / 60, rtol=1e-15)


def test_gcode_inch_and_incremental(machine, tmp_path):
    text = ("G20 G90 G0 X1. Y2. Z3. A10. C20.\n"   # inch absolute
            "G91 G1 X0.5 F10.\n"                  # incremental inch: X 1.5 in
            "A-5. C+90.\n"                        # incremental degrees
            "G21 Y-10\n"                          # incremental mm
            "G90 X0 Z100 F600\n"                  # absolute mm
            "G91 Z-0.5\n")
    report = read_gcode_report(write(tmp_path, "ic.tap", text), machine)
    deg = np.radians
    expected = [[INCH, 2 * INCH, 3 * INCH, deg(10), deg(20)],
                [1.5 * INCH, 2 * INCH, 3 * INCH, deg(10), deg(20)],
                [1.5 * INCH, 2 * INCH, 3 * INCH, deg(5), deg(110)],
                [1.5 * INCH, 2 * INCH - 10, 3 * INCH, deg(5), deg(110)],
                [0, 2 * INCH - 10, 100, deg(5), deg(110)],
                [0, 2 * INCH - 10, 99.5, deg(5), deg(110)]]
    np.testing.assert_allclose(report.axes, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(report.toolpath.feed,
                               [np.nan, 10 * INCH / 60, 10 * INCH / 60, 10 * INCH / 60, 10, 10],
                               rtol=1e-15)


def test_gcode_crlf_and_lowercase(machine, tmp_path):
    path = tmp_path / "w.nc"
    path.write_bytes(b"%\r\n(dos file)\r\ng0 x1 y2 z3\r\n\r\ng1 x4 f120\r\n%\r\n")
    report = read_gcode_report(path, machine)
    np.testing.assert_array_equal(report.axes[:, :3], [[1, 2, 3], [4, 2, 3]])
    np.testing.assert_array_equal(report.lines, [3, 5])
    np.testing.assert_array_equal(report.toolpath.feed, [np.nan, 2.0])


def test_gcode_dwell_and_comments(machine, tmp_path):
    text = ("(SETUP) G0 X0 Y0 Z50 ; start\n"
            "g04 p0.5\n"
            "G4 X2.0 (dwell 2 s, X is time)\n"
            "  G1   X  10.  Y-.5 F 300. (odd   spacing)\n")
    report = read_gcode_report(write(tmp_path, "dw.gcode", text), machine)
    np.testing.assert_array_equal(report.axes[:, :3], [[0, 0, 50], [10, -0.5, 50]])
    np.testing.assert_array_equal(report.lines, [1, 4])


@pytest.mark.parametrize("text, match", [
    ("", r"no motion \(no G0/G1 block with an axis word\)"),
    ("%\n(ONLY SETUP)\nG90 G21\nM3 S1000\nM30\n%\n", r"no motion"),
    ("G0 X0 Y0\nG2 X10 Y0 I5 J0\n", r"row 2, field 'G': circular interpolation \(G2\)"),
    ("G0 X0 Y0\nG03 X10 Y0 R5\n", r"row 2, field 'G': circular interpolation \(G3\)"),
    ("G93 G1 X1 F10\n", r"row 1, field 'G': inverse-time feed \(G93\) is not supported"),
    ("G95\n", r"row 1, field 'G': feed per revolution \(G95\)"),
    ("G43.4 H1\n", r"row 1, field 'G': tool centre point control \(G43.4\)"),
    ("G0 X0\nG28 G91 Z0\n", r"row 2, field 'G': unsupported G code G28"),
    ("G0 X0\nG1 B45. F100\n", r"row 2, field 'B': unsupported word 'B45.' \(axes are X Y Z A C\)"),
    ("G0 X0\nG1 X1.2.3 F100\n", r"row 2, field 'X': cannot parse number 'X1.2.3'"),
    ("G0 X0\nG1 X Y1 F100\n", r"row 2, field 'X': cannot parse number 'X'"),
    ("G0 X0\r\nG1 Y- F100\r\n", r"row 2, field 'Y': cannot parse number 'Y-'"),
    ("G0 X0\n5 Y1\n", r"row 2: cannot parse '5Y1'"),
    ("G0 X0\nG1 X#1 F100\n", r"row 2, field 'X': cannot parse number 'X#1'"),
    ("G0 X0\n#1=5\n", r"row 2: cannot parse '#1=5'"),
    ("X0 Y0 Z10\n", r"row 1, field 'G': axis words before any motion code"),
    ("G0 G1 X0\n", r"row 1, field 'G': two codes of one modal group \(G0, G1\) in one block"),
    ("G0 X0\nG91 G90 X1\n", r"row 2, field 'G': two codes of one modal group \(G91, G90\)"),
    ("G0 X0\nG20 G21 X1\n", r"row 2, field 'G': two codes of one modal group \(G20, G21\)"),
    ("G0 X0 X1\n", r"row 1, field 'X': word X appears twice in the block"),
    ("G0 X0\nG1 X1 F100 F200\n", r"row 2, field 'F': word F appears twice in the block"),
    ("G0 X0\nG1 X1 F100\nG1 Q5 X2\nG2 X3 R1\n", r"row 3, field 'Q': unsupported word 'Q5'"),
    ("G0 X0\nG1 X1 F100\nG3 X0 Y1 R1\nG1 Q5 X2\n", r"row 3, field 'G': circular .*\(G3\)"),
    ("G0 X0\nG1 X1 F100 \u00e9\n", r"row 2: cannot parse '\u00e9'"),
    ("G0 X0\nG4 G1 X1 P1\n", r"row 2, field 'G': dwell \(G4\) and a motion code"),
    ("G0 X0\nG1 X1 (OPEN (NESTED) COMMENT)\n", r"row 2: unbalanced or nested"),
    ("G0 X0\nG1 X1 P2\n", r"row 2, field 'P': unsupported word 'P2'"),
    ("G0 X0\nG1 X1 F0\n", r"row 2, field 'F': feed must be positive, got F0"),
    ("G0 X0 Y0 Z0 A0 C0\n", r"row 1: fewer than 2 distinct points \(1 read"),
    ("G0 X0 Y0 Z0\nG1 X0 F100\nY0\n", r"row 1: fewer than 2 distinct points \(3 read, 2"),
    # A from +60 to -60 deg at the same C: the orientation turns by 120 deg in one block
    ("G0 X0 Y0 Z0 A60 C0\nG1 A-60 F100\n",
     r"row 2, field 'O': tool orientation turns by 120.0 deg \(more than 90\) in one move "
     r"from line 1"),
])
def test_gcode_errors(machine, tmp_path, text, match):
    path = write(tmp_path, "bad.nc", text)
    with pytest.raises(ToolPathError, match=match) as info:
        read_gcode(path, machine)
    assert str(info.value).startswith(str(path))


def _interpret(blocks):
    """Sequential reference interpreter for the random programs below."""
    q = np.zeros(5)
    inc, scale, out = False, 1.0, []
    for codes, words in blocks:
        if "G91" in codes:
            inc = True
        if "G90" in codes:
            inc = False
        if "G20" in codes:
            scale = INCH
        if "G21" in codes:
            scale = 1.0
        for j, name in enumerate("XYZAC"):
            if name in words:
                value = words[name] * (scale if j < 3 else 1.0)
                q[j] = q[j] + value if inc else value
        out.append(q.copy())
    q = np.array(out)
    q[:, 3:] = np.radians(q[:, 3:])
    return q


@pytest.mark.parametrize("seed", range(5))
def test_gcode_modal_state_matches_sequential_interpreter(machine, tmp_path, seed):
    rng = np.random.default_rng(seed)
    blocks, text = [], ["G0 X0 Y0 Z0 A0 C0"]
    blocks.append(((), {"X": 0.0, "Y": 0.0, "Z": 0.0, "A": 0.0, "C": 0.0}))
    for k in range(300):
        codes = tuple(rng.choice(["G90", "G91", "G20", "G21"],
                                 size=rng.integers(0, 3), replace=False))
        if {"G90", "G91"} <= set(codes) or {"G20", "G21"} <= set(codes):
            codes = codes[:1]
        names = [a for a in "XYZAC" if rng.random() < 0.5] or ["X"]
        words = {a: round(float(rng.uniform(-2, 2)), 4) for a in names}
        blocks.append((codes, words))
        text.append(f"N{k} " + " ".join(codes) + (" G1" if k == 0 else "") + " "
                    + " ".join(f"{a}{v:.4f}" for a, v in words.items()) + " F500")
    expected = _interpret(blocks)
    # keep the orientation turn per block small: the reader rejects > 90 deg
    report = read_gcode_report(write(tmp_path, "r.nc", "\n".join(text)), machine)
    keep = np.r_[True, np.any(np.diff(expected, axis=0) != 0, axis=1)]
    np.testing.assert_allclose(report.axes, expected[keep], rtol=0, atol=1e-9)


def test_gcode_needs_a_machine_with_kinematics(tmp_path):
    path = write(tmp_path, "a.nc", "G0 X0\nG1 X1 F100\n")
    with pytest.raises(InputError, match=r"field 'machine': reading G-code needs a machine .*"
                                         r"got NoneType"):
        read_gcode(path, None)
    assert read_gcode(path, "zhang2013").n_points == 2


# --------------------------------------------------------------------------- dispatcher


def test_read_toolpath_dispatches_by_extension(machine, tmp_path):
    apt = tmp_path / "part.ApT"
    apt.write_text("GOTO/0,0,0,0,0,1\nGOTO/1,0,0,0,0,1\n")
    csv = tmp_path / "part.CSV"
    csv.write_text("Px,Py,Pz,Oi,Oj,Ok\n0,0,0,0,0,1\n1,0,0,0,0,1\n")
    nc = tmp_path / "part.MPF"
    nc.write_text("G0 X0 Y0 Z0\nG1 X1 F60\n")
    assert read_toolpath_report(apt).format == "apt"
    assert read_toolpath_report(csv).format == "clcsv"
    report = read_toolpath_report(nc, machine="zhang2013")
    assert report.format == "gcode"
    np.testing.assert_array_equal(report.toolpath.feed, [np.nan, 1.0])
    np.testing.assert_array_equal(read_toolpath(csv).P, read_toolpath(apt).P)
    # a feed unit reaches the CL readers
    apt.write_text("FEDRAT/5\nGOTO/0,0,0\nGOTO/1,0,0\n")
    np.testing.assert_array_equal(read_toolpath(apt, feed_units="mm/s").feed, [5.0, 5.0])


def test_read_toolpath_extension_table_and_format_override(tmp_path):
    for name, suffixes in EXTENSIONS.items():
        for suffix in suffixes:
            assert toolpath_format(f"x{suffix.upper()}") == name
    txt = write(tmp_path, "path.txt", "GOTO/0,0,0\nGOTO/0,0,1\n")
    assert read_toolpath(txt, format="apt").n_points == 2


@pytest.mark.parametrize("name, kwargs, error, match", [
    ("path.txt", {}, ToolPathError, r"path.txt: unknown tool-path extension '.txt'; supported: "
                                    r".csv, .apt, .cls, .cl, .aptsource, .nc, .ngc"),
    ("path", {}, ToolPathError, r"unknown tool-path extension '\(none\)'"),
    ("path.apt", {"format": "step"}, InputError, r"field 'format': unknown tool-path format"),
    ("path.nc", {}, ToolPathError, r"path.nc: G-code gives machine-axis positions: reading "
                                   r"it needs a machine"),
])
def test_read_toolpath_errors(tmp_path, name, kwargs, error, match):
    path = write(tmp_path, name, "G0 X0\nG1 X1 F100\n")
    with pytest.raises(error, match=match):
        read_toolpath(path, **kwargs)
