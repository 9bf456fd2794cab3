"""The controllers' servo traces (TNCscope, TwinCAT Scope View, Sinumerik Operate) and any CSV:
each sample file of ``data/`` (layouts and their public sources: data/SOURCES.md) reads to the
same log as a halsampler log of the same motion; channels are recognised by their names or
named by a map; every problem is one line naming the file, row and field."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from precontour.cli import main
from precontour.errors import InputError, PrecontourError
from precontour.identification import identify, parse_column_map
from precontour.identification._log_reading import Letters
from precontour.identification._trace_formats import recognise
from precontour.identification.servo_log import read_servo_log
from precontour.machine import load_machine
from precontour.machine.machine_file import machine_data
from precontour.tables import write_columns

from trace_samples import (AXES, CSV_HEADERS, DATA, N, PERIOD, csv_text, halsampler_text, motion,
                           sco_text, sinumerik_text, tnc_number, twincat_text, write_samples)

DEG = np.pi / 180
#: The halsampler reference's columns after the sample number.
NAMES = [name for a in AXES for name in (a, f"{a}_act")] + ["line"]
#: Each sample, its format, and the columns it is read with (None: recognised by name).
READ = {"tncscope.sco": ("sco", None), "twincat_tab.csv": ("twincat-csv", None),
        "twincat_semicolon.csv": ("twincat-csv", None),
        "twincat_comma.csv": ("twincat-csv", None),
        "sinumerik_trace.xml": ("sinumerik-xml", None),
        "spreadsheet.csv": ("csv", CSV_HEADERS)}
#: The samples that record the program line.
WITH_LINE = {"twincat_semicolon.csv", "spreadsheet.csv"}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The motion as LinuxCNC's halsampler records it, read as every log is read: degrees."""
    path = tmp_path_factory.mktemp("reference") / "motion.log"
    path.write_text(halsampler_text(NAMES))
    return read_servo_log(path, fmt="halsampler", columns=["n"] + NAMES, default_period=PERIOD,
                          angle_scale=DEG)


def _same_motion(log, reference, line: bool) -> None:
    assert log.axes == AXES and log.n_samples == N
    np.testing.assert_allclose(log.t, reference.t, rtol=0, atol=1e-9)
    for a in AXES:
        np.testing.assert_allclose(log.command[a], reference.command[a], rtol=0, atol=1e-9)
        np.testing.assert_allclose(log.actual[a], reference.actual[a], rtol=0, atol=1e-9)
    if line:
        np.testing.assert_array_equal(log.line, reference.line)
        assert log.line.dtype == np.int64
    else:
        assert log.line is None


def test_the_reference_holds_the_motion(reference):
    m = motion()
    np.testing.assert_allclose(reference.t, m["t"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(reference.actual["C"], m["C_act"] * DEG, rtol=0, atol=1e-12)
    assert reference.line.tolist()[::50] == [20, 22, 24, 26]


@pytest.mark.parametrize("name", READ)
def test_each_trace_reads_as_the_halsampler_log_of_its_motion(reference, name):
    fmt, columns = READ[name]
    found = read_servo_log(DATA / name, columns=columns, angle_scale=DEG)   # format by the file
    _same_motion(found, reference, name in WITH_LINE)
    told = read_servo_log(DATA / name, fmt=fmt, columns=columns, angle_scale=DEG)
    np.testing.assert_array_equal(told.command["Z"], found.command["Z"])
    assert found.period == pytest.approx(PERIOD, rel=1e-12)


def test_the_sample_files_are_what_the_writer_writes(tmp_path):
    for path in write_samples(tmp_path):
        assert path.read_bytes() == (DATA / path.name).read_bytes(), path.name


def test_rotary_units_and_microns_of_tncscope(tmp_path, reference):
    """Degrees ('°' in the Windows code page) are read as degrees; µm are turned into mm."""
    text = sco_text()
    assert "%DIMENSION=°" in text
    microns = text.split("\r\n")
    data = microns.index("%[DATA]")
    curve = microns.index("%NAME=s ist/Y")
    microns[curve + 4] = "%DIMENSION=µm"
    column = int(microns[curve + 13].split("=")[1])
    for k in range(data + 1, data + 1 + N):
        cells = microns[k].split(";")
        cells[column] = f" {float(cells[column]) * 1e3:.15e}"
        microns[k] = ";".join(cells)
    path = tmp_path / "microns.sco"
    path.write_bytes("\r\n".join(microns).encode("cp1252"))
    _same_motion(read_servo_log(path, angle_scale=DEG), reference, line=False)
    path.write_bytes("\r\n".join(microns).replace("%DIMENSION=µm", "%DIMENSION=inch")
                     .encode("cp1252"))
    with pytest.raises(InputError, match=r"microns\.sco, field 's ist/Y': unit 'inch' of channel "
                                         r"'s ist/Y': positions are read in mm, µm or degrees"):
        read_servo_log(path)


def test_a_tncscope_acceleration_of_axis_a_is_no_position(tmp_path, reference):
    """The type 'a soll' of axis A has the letter A twice, and neither is A's position."""
    text = sco_text().replace("%NAME=v ist/X\r\n%CHANNELTYPE=v ist\r\n%CHANNELID=6\r\n"
                              "%AXISTYPE=X\r\n%DIMENSION=mm/min",
                              "%NAME=a soll/A\r\n%CHANNELTYPE=a soll\r\n%CHANNELID=6\r\n"
                              "%AXISTYPE=A\r\n%DIMENSION=m/s^2")
    assert "a soll/A" in text
    path = tmp_path / "accel.sco"
    path.write_bytes(text.encode("cp1252"))
    _same_motion(read_servo_log(path, angle_scale=DEG), reference, line=False)


@pytest.mark.parametrize("label, name", [
    ("s soll/X", "X"), ("s ist/C", "C_act"), ("s nom/Y", "Y"), ("s actl/Y", "Y_act"),
    ("Lagesollwert X1", "X"), ("Lageistwert Messsystem 2 Z1", "Z_act"),
    ("Position setpoint Y1", "Y"), ("Actual position value measuring system 1 C1", "C_act"),
    ("MAIN.AxisX.NcToPlc.SetPos", "X"), ("MAIN.AxisA.NcToPlc.ActPos", "A_act"),
    ("X_act", "X_act"), ("Line", "line"), ("position demand value Z", "Z"),
    ("MAIN.AxisX.NcToPlc.SetVelo", None), ("MAIN.AxisX.NcToPlc.PosDiff", None),
    ("MAIN.AxisC.NcToPlc.ModuloActPos", None), ("MAIN.AxisX.NcToPlc.TargetPos", None),
    ("Konturabweichung X1", None), ("Schleppabstand X1", None), ("I ist/X", None),
    ("v soll/Y", None), ("/Nck/!SD/nckServoDataActPos1stEnc64 [u1, 1]", None),
    ("SetPos X Y", None), ("X setpoint actual", None), ("X", "X"), ("SetPos B", None),
])
def test_channel_names_recognised_in_english_and_german(label, name):
    assert recognise(label, Letters(tuple(AXES))) == name


def test_a_b_c_machines_letter_b_is_recognised():
    letters = Letters(("X", "Y", "Z", "B", "C"))
    assert recognise("SetPos B", letters) == "B"
    assert recognise("Lageistwert B1", letters) == "B_act"


@pytest.mark.parametrize("text, expected", [
    ("Pos X=X,Act X=X_act", {"Pos X": "X", "Act X": "X_act"}),
    (" s soll/X = X , s ist/X=X_act ,", {"s soll/X": "X", "s ist/X": "X_act"}),
    ("/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 1]=X_act,Zeit=t",
     {"/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 1]": "X_act", "Zeit": "t"}),
    ('"a=b"=line,Spindle=', {"a=b": "line", "Spindle": ""}),
])
def test_column_maps(text, expected):
    assert parse_column_map(text) == expected


@pytest.mark.parametrize("text, message", [
    ("", "column map is empty"), ("=X", "a pair without a header"),
    ("A=X,A=Y", "header 'A' mapped twice"), ("B=Y,A=X=Y", "expected header=name at 'A=X=Y'"),
])
def test_bad_column_maps(text, message):
    with pytest.raises(InputError, match=re.escape(message)) as info:
        parse_column_map(text)
    assert "\n" not in str(info.value)


def _with_line_changed(text: str, marker: str, old: str, new: str) -> tuple[str, int]:
    """``text`` with ``old`` replaced by ``new`` on the first line holding ``marker``, and
    that line's number."""
    lines = text.splitlines(keepends=True)
    k = next(i for i, line in enumerate(lines) if marker in line)
    assert old in lines[k]
    lines[k] = lines[k].replace(old, new, 1)
    return "".join(lines), k + 1


def _bad_number_cases():
    m = motion()
    y_act = f"{m['Y_act'][37]:.16g}"
    yield ("trace.sco", sco_text(), "cp1252", tnc_number(m["Y_act"][37]), "s ist/Y")
    yield ("tab.csv", twincat_text("\t", False, ",", False), "utf-8", y_act.replace(".", ","),
           "MAIN.AxisY.NcToPlc.ActPos")
    yield ("semi.csv", twincat_text(";", True, ".", True), "utf-8", y_act, "ActPos 2")
    yield ("trace.xml", sinumerik_text(), "utf-8", y_act,
           "/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, 2]")
    yield ("sheet.csv", csv_text(), "utf-8", y_act.replace(".", ","), "Pos Y ist")


@pytest.mark.parametrize("name, text, encoding, value, field", list(_bad_number_cases()),
                         ids=[case[0] for case in _bad_number_cases()])
def test_a_bad_number_names_the_file_row_and_channel(tmp_path, name, text, encoding, value,
                                                    field):
    bad, row = _with_line_changed(text, value, value, "1.2.3")
    path = tmp_path / name
    path.write_bytes(bad.encode(encoding))
    columns = CSV_HEADERS if name == "sheet.csv" else None
    with pytest.raises(InputError) as info:
        read_servo_log(path, columns=columns)
    assert str(info.value) == f"{path}, row {row}, field {field!r}: not a number: '1.2.3'"


def test_a_map_naming_no_channel_or_no_column(tmp_path):
    path = DATA / "tncscope.sco"
    with pytest.raises(InputError, match=r"tncscope\.sco, field 's ist/Q': no channel 's ist/Q' in "
                                         r"the file; it has 's soll/X', 's ist/X', 'v ist/X', "
                                         r"'s soll/Y', .* and 4 more"):
        read_servo_log(path, columns={"s soll/X": "X", "s ist/Q": "X_act"})
    with pytest.raises(InputError, match=r"field 'Q': unknown column name 'Q'"):
        read_servo_log(path, columns={"s soll/X": "X", "s ist/X": "Q"})
    with pytest.raises(InputError, match=r"column 't' names no channel of a trace"):
        read_servo_log(path, columns={"s soll/X": "t"})
    log = read_servo_log(path, columns={"CURVE1": "X", "s ist/X": "X_act"})    # by section
    assert log.axes == ("X",)
    with pytest.raises(InputError, match=r"field 'CURVE2': the column map names channel "
                                         r"'s ist/X' twice"):
        read_servo_log(path, columns={"s ist/X": "X_act", "CURVE2": "X"})
    with pytest.raises(InputError, match=r"no channel of the trace is read: the columns name none"):
        read_servo_log(path, columns={"s ist/X": ""})


def test_channels_that_name_no_axis_are_listed(tmp_path):
    """Sinumerik names a signal by its machine axis number: without the axis in its
    description it is named with a map (by signal name, description or id)."""
    text = sinumerik_text()
    for axis in AXES:
        text = text.replace(f' {axis}1"', '"')
    path = tmp_path / "numbers.xml"
    path.write_text(text)
    with pytest.raises(InputError, match=r"numbers\.xml: no channel is recognised as an axis "
                                         r"position: '/Nck/!SEMA/cmdContrPos \[u1, 1\]', .* and 3 "
                                         r"more; name them with a column map"):
        read_servo_log(path)
    log = read_servo_log(path, columns={"/Nck/!SEMA/cmdContrPos [u1, 3]": "Z", "f6": "Z_act"})
    assert log.axes == ("Z",)
    log = read_servo_log(DATA / "sinumerik_trace.xml",
                         columns={"Lagesollwert Z1": "Z", "Lageistwert Messsystem 2 Z1": "Z_act"})
    assert log.axes == ("Z",)


def test_two_channels_of_one_column_are_not_guessed(tmp_path):
    text = sinumerik_text().replace('description="Konturabweichung X1"',
                                    'description="Lageistwert Messsystem 1 X1"')
    path = tmp_path / "two.xml"
    path.write_text(text)
    with pytest.raises(InputError, match=r"channels '/Nck/!SD/nckServoDataActPos2ndEnc64 \[u1, 1\]' "
                                         r"and '/Nck/!SD/nckServoDataContDev64 \[u1, 1\]' both read "
                                         r"as X_act: name the one to use with a column map"):
        read_servo_log(path)


def test_an_axis_without_its_actual_position(tmp_path):
    """A trace read for its timing has commands only: refused unless require_actual=False."""
    path = DATA / "twincat_semicolon.csv"
    columns = {"SetPos 1": "X", "ActPos 1": "X_act", "SetPos 2": "Y"}
    with pytest.raises(InputError, match=r"twincat_semicolon\.csv, field 'Y_act': axis Y has only "
                                         r"one of Y, Y_act \(a trace read for its timing only"):
        read_servo_log(path, columns=columns)
    log = read_servo_log(path, columns=columns, require_actual=False)
    assert log.axes == ("X", "Y") and set(log.actual) == {"X"}
    with pytest.raises(InputError, match=r"field 'Y': axis Y has only one of Y, Y_act"):
        read_servo_log(path, columns={"ActPos 2": "Y_act", "SetPos 1": "X"},
                       require_actual=False)
    timing = tmp_path / "timing.csv"
    timing.write_text(path.read_text().replace("ActPos", "PosDiff"))   # following errors
    only = read_servo_log(timing, require_actual=False)
    assert only.axes == AXES and not only.actual and only.line is not None


def test_identify_keeps_the_base_model_of_an_axis_without_actual_positions():
    log = read_servo_log(DATA / "twincat_semicolon.csv", require_actual=False,
                         columns={"SetPos 1": "X", "SetPos 2": "Y"})
    base = load_machine("zhang2013")
    with pytest.raises(InputError, match="axis X: the log has its command but not its actual "
                                         "position; kept the base model"):
        identify(log, base, machine_data("zhang2013")[0])


def test_program_lines_from_every_format(tmp_path, reference):
    m = motion()
    scope = tmp_path / "scope.txt"
    scope.write_text("# Sampling period is 1000000 ns\nX;X_act;line\n" + "".join(
        f"{m['X'][k]:.17g};{m['X_act'][k]:.17g};{m['line'][k]:g}\n" for k in range(N)))
    table = write_columns(tmp_path / "table.csv", {"t": m["t"], "X": m["X"],
                                                   "X_act": m["X_act"], "line": m["line"]})
    for path in (scope, table):
        np.testing.assert_array_equal(read_servo_log(path).line, reference.line)
    broken = tmp_path / "broken.csv"
    text, row = _with_line_changed(csv_text(), f";{m['line'][60]:g}\n", f";{m['line'][60]:g}\n",
                                   ";22,5\n")
    broken.write_text(text)
    with pytest.raises(InputError, match=rf"broken\.csv, row {row}, field 'line': a program line "
                                         r"must be a whole number, got 22\.5"):
        read_servo_log(broken, columns=CSV_HEADERS)


def test_csv_by_a_list_of_names_with_or_without_a_header(tmp_path, reference):
    m = motion()
    plain = tmp_path / "plain.txt"
    plain.write_text("# t X X_act\n" + "".join(
        f"{m['t'][k]:.17g} {m['X'][k]:.17g} {m['X_act'][k]:.17g}\n" for k in range(N)))
    log = read_servo_log(plain, fmt="csv", columns=["t", "X", "X_act"])
    np.testing.assert_allclose(log.command["X"], reference.command["X"], rtol=0, atol=1e-12)
    sheet = DATA / "spreadsheet.csv"
    order = ["t", ""] + list(CSV_HEADERS.values())[1:]
    _same_motion(read_servo_log(sheet, columns=order, angle_scale=DEG), reference, line=True)
    with pytest.raises(InputError, match=r"plain\.txt, row 2: a column map needs a header line"):
        read_servo_log(plain, fmt="csv", columns={"X": "X"})
    with pytest.raises(InputError, match=r"plain\.txt: name the columns"):
        read_servo_log(plain, fmt="csv")
    with pytest.raises(InputError, match=r"plain\.txt: no column of the file is read"):
        read_servo_log(plain, fmt="csv", columns=["", "", ""])


def test_twincat_channels_of_different_time_stamps(tmp_path):
    lines = twincat_text(",", False, ".", False).split("\r\n")
    k = next(i for i, line in enumerate(lines) if line.startswith("120,"))
    cells = lines[k].split(",")
    cells[2] = "120.5"            # the time column of the second channel, X's ActPos
    lines[k] = ",".join(cells)
    path = tmp_path / "times.csv"
    path.write_text("\r\n".join(lines))
    with pytest.raises(InputError, match=rf"times\.csv, row {k + 1}, field "
                                         r"'MAIN\.AxisX\.NcToPlc\.ActPos': channels "
                                         r"'MAIN\.AxisX\.NcToPlc\.SetPos' and "
                                         r"'MAIN\.AxisX\.NcToPlc\.ActPos' have different time "
                                         r"stamps"):
        read_servo_log(path)


@pytest.mark.parametrize("name, text, message", [
    ("a.sco", "%TNCscopeNT data file\n%[CURVE1]\n%NAME=s ist/X\n1;2;\n",
     r"a\.sco, row 4: a row of values before the '%\[DATA\]' line"),
    ("b.sco", "TNCscope\n", r"b\.sco, row 1: not a TNCscope data file"),
    ("c.sco", "%x\n%[CURVE1]\n%COLUMN=zero\n%[DATA]\n", r"c\.sco, row 2, field 'COLUMN': "
                                                        r"COLUMN='zero' is no valid count"),
    ("d.txt", "Name:scope\n", r"d\.txt, row 1: separator ':': export with tab, ';' or ','"),
    ("e.csv", "Name;scope\n\n0;1;2\n", r"e\.csv, row 3: values before the channel header"),
    ("f.xml", "<trace/>", r"f\.xml, row 1: not a Sinumerik trace: the root element is <trace>"),
    ("g.xml", "<traceSession><rec time='0' f1='1'/>",
     r"g\.xml, row 1, field 'f1': a value of no dataSignal"),
    ("h.xml", "<!DOCTYPE x [<!ENTITY a 'b'>]><traceSession/>",
     r"h\.xml, row 1: a document type or entity declaration"),
    ("i.xml", "<traceSession><dataSignal id='f1' name='s'/>",
     r"i\.xml, row 1: not a well-formed XML file: no element found"),
])
def test_files_that_are_no_trace(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    fmt = "twincat-csv" if name == "d.txt" else None
    with pytest.raises(InputError, match=message) as info:
        read_servo_log(path, fmt=fmt)
    assert "\n" not in str(info.value)


def test_the_command_line_reads_a_column_map(tmp_path, capsys):
    text, row = _with_line_changed(csv_text(), "0,005;12000", "0,005;", "x;")
    sheet = tmp_path / "sheet.csv"
    sheet.write_text(text)
    column_map = ",".join(f"{header}={name}" for header, name in CSV_HEADERS.items())
    assert main(["identify", str(sheet), "--column-map", column_map, "--angles", "deg",
                 "-o", str(tmp_path / "out.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"{sheet}, row {row}, field 'Zeit [s]': not a number: 'x'"), err
    assert main(["identify", str(sheet), "--column-map", "Zeit [s]", "-o",
                 str(tmp_path / "out.toml")]) == 2
    assert "column map 'Zeit [s]': expected header=name" in capsys.readouterr().err


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=600),
       fmt=st.sampled_from(["sco", "twincat-csv", "sinumerik-xml", "csv"]))
def test_arbitrary_bytes_raise_only_our_errors(tmp_path, data, fmt):
    path = tmp_path / "fuzz.log"
    path.write_bytes(data)
    try:
        read_servo_log(path, fmt=fmt, columns=["t", "X", "X_act"] if fmt == "csv" else None)
    except PrecontourError as exc:
        assert "\n" not in str(exc)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.integers(0, 4000), junk=st.sampled_from(["", "x", ";", "\n", "<", "%[DATA]",
                                                        "Name;", "EOF", "1e999", "\x00"]),
       name=st.sampled_from(sorted(READ)))
def test_damaged_samples_raise_only_our_errors(tmp_path, cut, junk, name):
    """A sample cut anywhere in its first 4000 bytes, with junk appended, reads or is refused in
    one line."""
    path = tmp_path / name
    path.write_bytes((DATA / name).read_bytes()[:cut] + junk.encode())
    try:
        read_servo_log(path, columns=READ[name][1])
    except PrecontourError as exc:
        assert "\n" not in str(exc)
