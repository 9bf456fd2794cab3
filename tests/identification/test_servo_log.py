"""Servo log readers: the three formats, and one-line errors naming file, row and field."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from precontour.errors import InputError, PrecontourError
from precontour.identification.servo_log import read_servo_log
from precontour.machine.drives import AXES
from precontour.tables import write_columns

N = 50


def _columns(n=N, currents=False):
    t = np.arange(n) * 1e-3
    cols = {"t": t}
    for i, a in enumerate(AXES):
        cols[a] = np.sin(t * (i + 1))
        cols[f"{a}_act"] = cols[a] - 1e-3 * i
        if currents:
            cols[f"I_{a}"] = np.cos(t * (i + 1)) * (1 + 0.01 * np.arange(n) / n)
    return cols


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".parquet"])
def test_table_round_trip(tmp_path, suffix):
    cols = _columns(currents=True)
    path = write_columns(tmp_path / f"log{suffix}", cols)
    log = read_servo_log(path)
    np.testing.assert_array_equal(log.t, cols["t"])
    for a in AXES:
        np.testing.assert_array_equal(log.command[a], cols[a])
        np.testing.assert_array_equal(log.actual[a], cols[f"{a}_act"])
        np.testing.assert_array_equal(log.current[a], cols[f"I_{a}"])
    assert log.period == pytest.approx(1e-3)


def test_degrees_are_converted(tmp_path):
    cols = _columns()
    path = write_columns(tmp_path / "log.csv", cols)
    log = read_servo_log(path, angle_scale=np.pi / 180)
    np.testing.assert_allclose(log.command["A"], cols["A"] * np.pi / 180)
    np.testing.assert_array_equal(log.command["X"], cols["X"])


def test_missing_axes_are_allowed_but_not_half_an_axis(tmp_path):
    cols = {k: v for k, v in _columns().items() if k in ("t", "X", "X_act", "C")}
    with pytest.raises(InputError, match=r"field 'C_act'.*only one of C, C_act"):
        read_servo_log(write_columns(tmp_path / "a.csv", cols))
    del cols["C"]
    assert read_servo_log(write_columns(tmp_path / "b.csv", cols)).axes == ("X",)


@pytest.mark.parametrize("change, message", [
    (lambda c: c["Y_act"].__setitem__(7, np.nan), r"b\.csv, row 8, field 'Y_act': value is not finite"),
    (lambda c: c["t"].__setitem__(20, c["t"][20] + 0.0004), r"row 21, field 't': time is not uniformly"),
    (lambda c: c["t"].__setitem__(slice(30, None), c["t"][30:] + 0.005), r"b\.csv, row 31, field 't': gap"),
    (lambda c: c["I_Z"].__setitem__(slice(10, 14), 99.0), r"row 11, field 'I_Z': saturated"),
])
def test_bad_samples_name_file_row_and_field(tmp_path, change, message):
    cols = _columns(currents=True)
    change(cols)
    path = tmp_path / "b.csv"
    write_columns(path, cols)
    with pytest.raises(InputError, match=message) as info:
        read_servo_log(path)
    assert "\n" not in str(info.value)


def _halsampler_text(tagged=True, skip_at=None, overrun_at=None):
    lines = []
    for k in range(N):
        if overrun_at == k:
            lines.append("overrun")
        number = k + (5 if skip_at is not None and k >= skip_at else 0)
        values = [f"{np.sin(k * 1e-3):.9f}", f"{np.sin(k * 1e-3) - 1e-4:.9f}", "1", f"{k}"]
        lines.append(" ".join(([str(number)] if tagged else []) + values))
    return "\n".join(lines) + "\n"


def test_halsampler_with_sample_numbers(tmp_path):
    path = tmp_path / "hal.log"
    path.write_text(_halsampler_text())
    log = read_servo_log(path, columns=["n", "X", "X_act", "", "I_X"], default_period=1e-3)
    assert log.axes == ("X",) and log.n_samples == N
    np.testing.assert_allclose(log.t, np.arange(N) * 1e-3)
    np.testing.assert_allclose(log.actual["X"], np.sin(np.arange(N) * 1e-3) - 1e-4, atol=1e-9)


def test_halsampler_gap_and_overrun_are_errors(tmp_path):
    path = tmp_path / "gap.log"
    path.write_text(_halsampler_text(skip_at=30))
    with pytest.raises(InputError, match=r"gap\.log, row 31, field 'n': sample number jumps"):
        read_servo_log(path, columns=["n", "X", "X_act", "", ""], default_period=1e-3)
    path.write_text(_halsampler_text(overrun_at=12))
    with pytest.raises(InputError, match=r"row 13: halsampler overrun"):
        read_servo_log(path, columns=["n", "X", "X_act", "", ""], default_period=1e-3)


def test_halsampler_needs_names_and_numbers(tmp_path):
    path = tmp_path / "hal.log"
    path.write_text(_halsampler_text(tagged=False))
    with pytest.raises(InputError, match="name the columns"):
        read_servo_log(path, default_period=1e-3)
    with pytest.raises(InputError, match="2 column names for 4 values"):
        read_servo_log(path, columns=["X", "X_act"], default_period=1e-3)
    text = path.read_text().splitlines()
    text[9] = text[9].replace("1 ", "one ", 1) if " 1 " in text[9] else text[9] + " x"
    path.write_text("\n".join(text))
    with pytest.raises(InputError, match=r"row 10"):
        read_servo_log(path, columns=["X", "X_act", "", "I_X"], default_period=1e-3)


def test_halscope_current_format(tmp_path):
    rows = [f"{np.sin(k * 2e-3):.6f};{np.sin(k * 2e-3) - 2e-4:.6f};{k % 2}" for k in range(N)]
    path = tmp_path / "scope.txt"
    path.write_text("# Sampling period is 2000000 ns\nX;X_act;spindle\n# Position: 0.5;0.5;0.5\n"
                    "# Scale: 3;3;3\n" + "\n".join(rows) + "\n")
    log = read_servo_log(path)
    assert log.axes == ("X",) and log.n_samples == N
    assert log.period == pytest.approx(2e-3)
    log = read_servo_log(path, columns=["Y", "Y_act", ""])
    assert log.axes == ("Y",)


def test_halscope_old_format_drops_the_row_past_the_capture(tmp_path):
    rows = [f"joint.0.pos-cmd {np.sin(k * 1e-3):+.14f} joint.0.pos-fb {np.sin(k * 1e-3) - 1e-4:+.14f} "
            for k in range(N + 1)]
    path = tmp_path / "old.log"
    path.write_text("Sampling period is 1000000 ns \n\n" + "\n".join(rows) + "\n")
    log = read_servo_log(path, columns=["X", "X_act"])
    assert log.n_samples == N
    np.testing.assert_allclose(log.command["X"], np.sin(np.arange(N) * 1e-3), atol=1e-14)
    lines = path.read_text().splitlines()
    lines[5] = lines[5].replace("joint.0.pos-fb", "joint.9.pos-fb")
    path.write_text("\n".join(lines))
    with pytest.raises(InputError, match=r"old\.log, row 6: labels .* differ"):
        read_servo_log(path, columns=["X", "X_act"])


def test_halscope_bad_period(tmp_path):
    path = tmp_path / "scope.txt"
    path.write_text("# Sampling period is -5 ns\nX;X_act\n1;1\n")
    with pytest.raises(InputError, match=r"row 1, field 'Sampling period'"):
        read_servo_log(path)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=600), fmt=st.sampled_from(["halsampler", "halscope", "table"]),
       suffix=st.sampled_from([".log", ".csv", ".npz", ".parquet"]))
def test_arbitrary_bytes_raise_only_our_errors(tmp_path, data, fmt, suffix):
    path = tmp_path / f"fuzz{suffix}"
    path.write_bytes(data)
    try:
        read_servo_log(path, fmt=fmt, columns=["n", "X", "X_act"], default_period=1e-3)
    except PrecontourError as exc:
        assert "\n" not in str(exc)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=st.lists(st.lists(st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr), st.sampled_from(["overrun", "x", "", "1e999"]),
    st.integers(-3, 3).map(str)), min_size=0, max_size=4), max_size=40),
    header=st.sampled_from(["", "# Sampling period is 1000000 ns\n", "Sampling period is 1e6 ns\n"]),
    sep=st.sampled_from([" ", ";"]))
def test_structured_garbage_raises_only_our_errors(tmp_path, lines, header, sep):
    path = tmp_path / "fuzz.txt"
    path.write_text(header + "\n".join(sep.join(line) for line in lines))
    try:
        read_servo_log(path, columns=["n", "X", "X_act"] if not header else None,
                       default_period=1e-3)
    except PrecontourError as exc:
        assert "\n" not in str(exc)


def test_text_logs_are_refused_at_the_first_bad_line_without_reading_on(tmp_path):
    from precontour.identification.servo_log import MAX_LINE_BYTES
    path = tmp_path / "log.txt"
    good = "".join(f"{k} {k * 1e-3} {k * 1e-3}\n" for k in range(30))
    path.write_bytes(good.encode() + b"1 " * MAX_LINE_BYTES + b"\n" + good.encode())
    with pytest.raises(InputError, match=rf"log.txt, row 31: line longer than {MAX_LINE_BYTES} "
                                         r"bytes: not a servo log"):
        read_servo_log(path, fmt="halsampler", columns=["n", "X", "X_act"])
    path.write_bytes(good.encode() + b"\x00" * 100)
    with pytest.raises(InputError, match=r"log.txt, row 31: binary data, not a text log"):
        read_servo_log(path, fmt="halsampler", columns=["n", "X", "X_act"])
    path.write_bytes(b"\x1f\x8b" + good.encode())
    with pytest.raises(InputError, match=r"log.txt: gzip-compressed"):
        read_servo_log(path, fmt="halsampler", columns=["n", "X", "X_act"])
    path.write_bytes(b"Sampling period is 1000000 ns\n" + b"\xff\xfe" + b"X;X_act\n")
    with pytest.raises(InputError, match=r"log.txt, row 2: not a text file \(invalid UTF-8\)"):
        read_servo_log(path)


def test_zero_currents_are_refused_naming_the_column(tmp_path):
    cols = _columns(currents=True)
    cols["I_Y"] = np.zeros(N)
    path = write_columns(tmp_path / "log.csv", cols)
    with pytest.raises(InputError, match=r"log.csv, field 'I_Y': the motor current of Y is zero "
                                         r"on every row \(not recorded\?\)"):
        read_servo_log(path)


def _renamed(cols, old, new):
    """The columns with axis letter ``old`` spelled ``new`` (X_act, I_X too)."""
    out = {}
    for name, values in cols.items():
        for form in ("{}", "{}_act", "I_{}"):
            if name == form.format(old):
                name = form.format(new)
                break
        out[name] = values
    return out


@pytest.mark.parametrize("fmt", ["table", "halsampler"])
def test_a_b_c_machines_log_has_b_columns_and_still_reads_the_old_a(tmp_path, fmt, caplog):
    """On a B-C machine the tilt axis's columns are B, B_act, I_B (the machine's letters),
    read into the same slot as an X-Y-Z-A-C log's A: the same numbers either way. The former
    spelling, A holding B, is read too, with one notice."""
    from precontour.machine import load_machine

    letters = load_machine("linuxcnc-xyzbc-trt").axis_names
    assert tuple(letters) == ("X", "Y", "Z", "B", "C")
    cols = _columns(currents=True)
    reference = read_servo_log(write_columns(tmp_path / "ac.csv", cols))
    for name, spelled in (("b", _renamed(cols, "A", "B")), ("a", cols)):
        if fmt == "table":
            path = write_columns(tmp_path / f"{name}.csv", spelled)
            log = read_servo_log(path, axis_names=letters)
        else:
            path = tmp_path / f"{name}.txt"
            names = list(spelled)
            path.write_text("\n".join(" ".join(repr(float(spelled[c][k])) for c in names)
                                      for k in range(N)) + "\n")
            log = read_servo_log(path, fmt="halsampler", columns=names, axis_names=letters)
        for a in AXES:
            np.testing.assert_array_equal(log.command[a], reference.command[a])
            np.testing.assert_array_equal(log.actual[a], reference.actual[a])
            np.testing.assert_array_equal(log.current[a], reference.current[a])
        noted = "column A read as the B axis of this B-C machine" in caplog.text
        assert noted == (name == "a"), name
        caplog.clear()


def test_a_b_c_machines_messages_name_b(tmp_path):
    letters = ("X", "Y", "Z", "B", "C")
    cols = {k: v for k, v in _renamed(_columns(), "A", "B").items()
            if k in ("t", "X", "X_act", "B")}
    with pytest.raises(InputError, match=r"field 'B_act'.*only one of B, B_act"):
        read_servo_log(write_columns(tmp_path / "a.csv", cols), axis_names=letters)
    both = _renamed(_columns(), "A", "B")
    both.update(A=both["B"], A_act=both["B_act"])
    with pytest.raises(InputError, match="both column A and the machine's B"):
        read_servo_log(write_columns(tmp_path / "b.csv", both), axis_names=letters)
