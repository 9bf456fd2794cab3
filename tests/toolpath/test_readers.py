"""Tests of the tool-path readers: CL CSV, APT CL data, and the dispatcher (G-code programs:
test_gcode.py)."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from precontour.errors import InputError, ToolPathError
from precontour.machine.machine_file import load_machine
from precontour.toolpath import (EXTENSIONS, ToolPath, read_apt, read_apt_report, read_clcsv,
                                 read_clcsv_report, read_toolpath, read_toolpath_report, toolpath_format)

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
    (HEADER.rstrip("\n"), r"no data rows after the header"),
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


def test_clcsv_header_without_line_break_exits_cleanly(tmp_path):
    """A header with no line break after it (no data rows), read in a fresh interpreter that
    must then exit cleanly. With pyarrow 14 (the oldest allowed), reading it from a Python file
    object failed ("Empty CSV file or block") and left the reader's thread reading that file
    without the GIL it needed: the interpreter aborted at exit ("terminate called without an
    active exception"), and in a long test run the next read hung (the fuzz tests)."""
    import subprocess
    import sys

    path = write(tmp_path, "header.csv", HEADER.rstrip("\n"))
    code = ("import sys\nfrom precontour.errors import ToolPathError\n"
            "from precontour.toolpath import read_clcsv\n"
            "try:\n    read_clcsv(sys.argv[1])\nexcept ToolPathError as e:\n    print(e)\n")
    done = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "no data rows after the header" in done.stdout


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


def test_the_formats_are_the_command_lines(tmp_path):
    """--format offers the formats the readers read (precontour.defaults keeps the list so
    that --help imports no reader); a format given is checked, else the extension decides."""
    from precontour.defaults import TOOLPATH_FORMATS
    from precontour.toolpath.readers import FORMATS
    assert TOOLPATH_FORMATS == FORMATS == tuple(EXTENSIONS)
    assert toolpath_format("path.txt", "gcode") == "gcode"
    assert toolpath_format("path.csv", "apt") == "apt"
    with pytest.raises(InputError, match=r"field 'format': unknown tool-path format 'nc'; use "
                                         r"one of clcsv, apt, gcode"):
        toolpath_format("path.nc", "nc")


def test_a_heidenhain_program_is_read_by_its_reader(machine, tmp_path):
    """``.h``: Heidenhain conversational, read by its own reader; read as G-code (format
    given), its first block is refused as that language."""
    path = write(tmp_path, "spot.h", "0  BEGIN PGM spot MM\n1  L  X+0 Y+0 Z+15 A+0 C+0 R0 "
                                     "FMAX\n2  L  Z+5 F100\n3  END PGM spot MM\n")
    report = read_toolpath_report(path, machine=machine)
    assert report.format == "heidenhain" and report.toolpath.n_points == 2
    with pytest.raises(ToolPathError, match=r"spot.h, line 1: 'BEGIN PGM' is Heidenhain TNC "
                                            r"conversational syntax"):
        read_toolpath(path, machine=machine, format="gcode")


@pytest.mark.parametrize("name, kwargs, error, match", [
    ("path.txt", {}, ToolPathError, r"path.txt: unknown tool-path extension '.txt'; supported: "
                                    r".csv, .apt, .cls, .cl, .aptsource, .nc, .ngc, .gcode, "
                                    r".gc, .tap, .mpf, .cnc, .iso, .h \(or give the format, "
                                    r"--format or format=, one of clcsv, apt, gcode, "
                                    r"heidenhain\)"),
    ("path", {}, ToolPathError, r"unknown tool-path extension '\(none\)'"),
    ("path.apt", {"format": "step"}, InputError, r"field 'format': unknown tool-path format"),
    ("path.nc", {}, ToolPathError, r"path.nc: G-code gives machine-axis positions: reading "
                                   r"it needs a machine"),
])
def test_read_toolpath_errors(tmp_path, name, kwargs, error, match):
    path = write(tmp_path, name, "G0 X0\nG1 X1 F100\n")
    with pytest.raises(error, match=match):
        read_toolpath(path, **kwargs)
