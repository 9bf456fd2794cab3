import numpy as np
import pytest

from precontour import MachineFileError, load_machine
from precontour.errors import InputError
from precontour.machine.machine_file import parse_machine
from precontour.machine.machine_file import builtin_machine_text


def test_builtin_values_and_poles(machine):
    assert machine.name == "zhang2013"
    assert machine.kinematics.L_ac == 100.0 and machine.kinematics.L_ty == 300.0
    x = machine.drive("X")
    assert (x.ka, x.kt, x.rg, x.J, x.B) == (6.5723, 0.4769, 1.5915, 7.00e-3, 0.0236)
    assert x.friction.Ts_neg == -2.0692
    assert set(machine.controllers) == {"pid-high", "pid-low", "p-pi-high", "p-pi-low", "smc"}
    # spec section 2: closed-loop poles of X
    high = np.sort(machine.error_models("pid-high")[0].poles.real)
    low = np.sort(machine.error_models("pid-low")[0].poles.real)
    np.testing.assert_allclose(high, [-187.6, -58.8, -42.0], atol=0.05)
    np.testing.assert_allclose(low, [-178.3, -32.7, -6.1], atol=0.05)


def test_bandwidths_match_paper(machine):
    from scipy import signal
    # measured: 53.4-55.9 Hz and 35.9-38.6 Hz (rotary axes lowest); paper: 55.8 and 38.6 Hz
    for name, lo, hi in (("pid-high", 53.2, 56.2), ("pid-low", 35.7, 38.9)):
        for model, drive in zip(machine.error_models(name),
                                machine.drives):
            # x/X = 1 - e/X
            num = np.polysub(model.den, model.num)
            w = np.linspace(1, 2 * np.pi * 100, 20000)
            _, h = signal.freqs(num, model.den, w)
            f3 = w[np.argmax(np.abs(h) < 10 ** (-3 / 20))] / (2 * np.pi)
            assert lo < f3 < hi, (name, drive.axis, f3)


def test_friction_torque_signs(machine):
    f = machine.drive("X").friction
    w = np.array([-100.0, -1e-3, 0.0, 1e-3, 100.0])
    tf = f.torque(w)
    assert tf[2] == 0.0
    assert tf[0] < 0 and tf[1] < 0 and tf[3] > 0 and tf[4] > 0
    np.testing.assert_allclose(tf[3], f.Ts_pos, rtol=1e-3)          # static friction near 0+
    np.testing.assert_allclose(tf[4], f.Ts_pos * np.exp(-100 / 7.46) + f.Tc_pos *
                               (1 - np.exp(-100 / 7.46)))


def _edit(text, old, new):
    assert old in text
    return text.replace(old, new, 1)


@pytest.mark.parametrize("old, new, pattern", [
    ("L_ty = 300.0", "L_ty = ", r"malformed TOML"),
    ("L_ty = 300.0\n", "", r"\[kinematics\] L_ty: missing key"),
    ("J = 7.00e-3", "J = -7.00e-3", r"\[drives.X\] J: must be > 0"),
    ("J = 7.00e-3", "J = nan", r"\[drives.X\] J: must be finite"),
    ("J = 7.00e-3", "Jay = 7.00e-3", r"\[drives.X\] (Jay: unknown key|J: missing key)"),
    ("ka = 6.5723", "ka = \"six\"", r"\[drives.X\] ka: must be a number"),
    ("type = \"ac-trunnion\"", "type = \"hexapod\"", r"\[kinematics\] type: unknown value 'hexapod'"),
    ("type = \"pid\"", "type = \"fuzzy\"", r"\[controllers.pid-high\] type: unknown value 'fuzzy'"),
    ("X = { kp = 30.000,", "X = { kpp = 30.000,", r"\[controllers.pid-high.X\] kp: missing key"),
    ("Ts_neg = -2.0692", "Ts_neg = 2.0692", r"\[drives.X.friction\] Ts_neg: must be <= 0"),
    ("name = \"zhang2013\"", "name = \"zhang2013\"\nspeed = 3", r"speed: unknown key"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ng28 = [0, 0, 1]",
     r"\[gcode\] g28: must be a list of 5 finite numbers, the machine axes X Y Z A C \(mm, "
     r"rad\), got \[0, 0, 1\]"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ng29 = [0, 0, 0, 0, 0]",
     r"\[gcode\] g29: unknown key"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode.work_offsets]\nG60 = [0, 0, 0, 0, 0]",
     r"\[gcode.work_offsets\] G60: not a work offset; use G54 ... G59"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode.work_offsets]\nG59.1 = [0, 0, 0, 0, 0]",
     r"\[gcode.work_offsets\] G59: a dotted key: write names with a dot in quotes"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode.work_offsets]\n\"G54.1 P1\" = [0, 0, "
     "0, 0, 0]\n\"G54.1P1\" = [0, 0, 0, 0, 0]", r"G54.1P1: G54.1 P1 is given twice"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ntcp_on = [\"M6\"]",
     r"\[gcode\] tcp_on: M6 has a meaning of its own"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ntcp_on = \"M128\"",
     r"\[gcode\] tcp_on: must be a list of M or G codes such as \[\"M428\"\] or "
     r"\[\"G234\"\]"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ntcp_on = [\"TRAORI\"]",
     r"\[gcode\] tcp_on: 'TRAORI' is not an M or G code"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ntcp_on = [\"G1\"]",
     r"\[gcode\] tcp_on: G1 has a meaning of its own to the reader"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ntcp_off = [\"G234\"]",
     r"\[gcode\] tcp_off: G234 has a meaning of its own to the reader"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ntcp_on = [\"G43.7\"]\n"
     "tcp_off = [\"G43.7\"]", r"\[gcode\] tcp_off: G43.7 is in tcp_on too"),
    ("servo_period = 0.001", "servo_period = 0.001\n[tools]\nT0 = 5.0",
     r"\[tools\] T0: not a tool number"),
    ("servo_period = 0.001", "servo_period = 0.001\n[tools]\n1 = \"long\"",
     r"\[tools\] 1: must be a number"),
    ("servo_period = 0.001", "servo_period = 0.001\n[tools]\n1 = 1e6",
     r"\[tools\] 1: must be <= 10000"),
    ("servo_period = 0.001", "servo_period = 0.001\n[gcode]\ntcp_on = [\"M128\"]\n"
     "tcp_off = [\"M128\"]", r"\[gcode\] tcp_off: M128 is in tcp_on too"),
])
def test_machine_file_errors(tmp_path, old, new, pattern):
    path = tmp_path / "bad.toml"
    path.write_text(_edit(builtin_machine_text(), old, new))
    with pytest.raises(MachineFileError, match=pattern) as info:
        load_machine(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value).strip()


def test_gcode_settings(tmp_path):
    from precontour.machine.machine_file import builtin_machine_text
    text = builtin_machine_text("linuxcnc-xyzbc-trt") + (
        "\n[gcode]\ng30 = [1, 2, 3, 0.5, -1]\n[gcode.work_offsets]\n\"g59.1\" = [0, 0, 9, 0, 0]\n"
        "\"G54.1 p12\" = [1, 0, 0, 0, 0]\n")
    settings = parse_machine(text).gcode
    assert settings.g28 is None and settings.g30 == (1, 2, 3, 0.5, -1)
    assert dict(settings.work_offsets) == {"G59.1": (0, 0, 9, 0, 0), "G54.1 P12": (1, 0, 0, 0, 0)}
    assert settings.tcp_on == (428,) and settings.tcp_off == (429,)   # LinuxCNC's remaps
    assert load_machine("zhang2013").gcode.work_offsets == {}
    none = parse_machine(builtin_machine_text() + "[gcode]\ntcp_on = []\ntcp_off = []\n")
    assert none.gcode.tcp_on == () and none.gcode.tcp_off == ()
    # G codes: the reader's own TCP codes are accepted (read already), a site's own kept
    haas = parse_machine(builtin_machine_text() + '[gcode]\ntcp_on = ["G234", "G43.4", '
                         '"M428", "G43.7"]\ntcp_off = ["G49", "G43.8"]\n')
    assert haas.gcode.tcp_on == (428,) and haas.gcode.tcp_on_g == (437,)
    assert haas.gcode.tcp_off == () and haas.gcode.tcp_off_g == (438,)


def test_tools_table_gives_lengths_by_tool_number():
    machine = parse_machine(builtin_machine_text() + "[tools]\n1 = 50\nT12 = 80.5\n")
    assert dict(machine.tools) == {1: 50.0, 12: 80.5}
    assert dict(parse_machine(builtin_machine_text()).tools) == {}


def test_reserved_g_codes_are_the_readers_own():
    """RESERVED_G (machine package: no import of the reader) lists the G codes the reader
    reads with a meaning, less those it reads as TCP switches."""
    from precontour.machine.gcode import BUILTIN_TCP_OFF_G, BUILTIN_TCP_ON_G, RESERVED_G
    from precontour.toolpath._gcode_codes import _KNOWN_G
    assert RESERVED_G == _KNOWN_G - BUILTIN_TCP_ON_G - BUILTIN_TCP_OFF_G


def test_unknown_machine_and_controller(machine):
    with pytest.raises(MachineFileError, match="not a built-in machine"):
        load_machine("no-such-machine")
    with pytest.raises(MachineFileError, match=r"unknown controller 'pid-mid'.*pid-high, pid-low, p-pi-high, p-pi-low, smc"):
        machine.controller("pid-mid")


def test_machine_errors_are_value_errors():
    with pytest.raises(ValueError):
        parse_machine("name = 1")
    assert issubclass(MachineFileError, InputError)


def test_unstable_controller_is_rejected(tmp_path):
    from precontour.errors import UnsupportedControllerError
    text = _edit(builtin_machine_text(), "X = { kp = 30.000, ki = 650.00, kd = 0.4000 }",
                 "X = { kp = 0.01, ki = 650.00, kd = 0.0 }")
    path = tmp_path / "unstable.toml"
    path.write_text(text)
    m = load_machine(path)
    with pytest.raises(UnsupportedControllerError, match=r"axis X: closed loop is not stable"):
        m.error_models("pid-high")


@pytest.mark.parametrize("name, kin_type, axis_names", [
    ("linuxcnc-xyzac-trt", "XYZACTrunnion", ("X", "Y", "Z", "A", "C")),
    ("linuxcnc-xyzbc-trt", "XYZBCTrunnion", ("X", "Y", "Z", "B", "C")),
])
def test_linuxcnc_builtin_machines(name, kin_type, axis_names):
    machine = load_machine(name)
    zhang = load_machine("zhang2013")
    assert type(machine.kinematics).__name__ == kin_type
    assert machine.axis_names == axis_names == machine.kinematics.axis_names
    assert tuple(d.axis for d in machine.drives) == axis_names
    # the sim .ini's [JOINT_n] limits, degrees to rad
    tilt = machine.drive(axis_names[3])
    assert tilt is machine.drives[3] and tilt.is_rotary
    assert (tilt.p_min, tilt.p_max) == (np.radians(-100), np.radians(50))
    assert machine.kinematics.tilt_limits == (np.radians(-100), np.radians(50))
    assert (tilt.v_max, tilt.a_max) == (np.radians(30), np.radians(300))
    x = machine.drive("X")
    assert (x.p_min, x.p_max, x.v_max, x.a_max, x.j_max) == (-200, 200, 20, 300, 12000)
    assert (machine.drive("Y").p_max, machine.drive("Z").p_max) == (100, 120)
    assert machine.drive("C").p_max == pytest.approx(np.radians(36000), rel=1e-15)
    # drives and controllers are zhang2013's
    for ours, theirs in zip(machine.drives, zhang.drives):
        assert (ours.ka, ours.kt, ours.rg, ours.J, ours.B, ours.friction) == \
            (theirs.ka, theirs.kt, theirs.rg, theirs.J, theirs.B, theirs.friction)
    assert set(machine.controllers) == set(zhang.controllers)
    for model, reference in zip(machine.error_models("pid-high"),
                                zhang.error_models("pid-high")):
        np.testing.assert_array_equal(model.den, reference.den)


def test_sim_geometry_values():
    ac = load_machine("linuxcnc-xyzac-trt").kinematics
    assert (ac.y_offset, ac.z_offset, ac.tool_offset, ac.a_direction, ac.c_direction) == \
        (20, 10, 0, -1, -1)
    bc = load_machine("linuxcnc-xyzbc-trt").kinematics
    assert (bc.x_offset, bc.z_offset, bc.tool_offset, bc.b_direction, bc.c_direction) == \
        (-20, -15, 0, -1, -1)


@pytest.mark.parametrize("machine_name, old, new, pattern", [
    ("linuxcnc-xyzac-trt", 'type = "xyzac-trt"', 'type = "xyzac-trunnion"',
     r"\[kinematics\] type: unknown value 'xyzac-trunnion'; choose one of ac-trunnion, "
     r"xyzac-trt, xyzbc-trt"),
    ("linuxcnc-xyzac-trt", "y_offset = 20.0\n", "", r"\[kinematics\] y_offset: missing key"),
    ("linuxcnc-xyzac-trt", "y_offset = 20.0", "y_ofset = 20.0",
     r"\[kinematics\] (y_ofset: unknown key|y_offset: missing key)"),
    ("linuxcnc-xyzac-trt", "y_offset = 20.0", "y_offset = 20.0\nx_offset = 1.0",
     r"\[kinematics\] x_offset: unknown key"),
    ("linuxcnc-xyzac-trt", "a_direction = -1", "a_direction = 0",
     r"\[kinematics\] a_direction: must be \+1 or -1"),
    ("linuxcnc-xyzac-trt", 'tool_offset = 0.0', 'tool_offset = "long"',
     r"\[kinematics\] tool_offset: must be a number"),
    ("linuxcnc-xyzbc-trt", "x_offset = -20.0\n", "", r"\[kinematics\] x_offset: missing key"),
    ("linuxcnc-xyzbc-trt", "c_direction = -1\n", "",
     r"\[kinematics\] c_direction: missing key"),
    ("linuxcnc-xyzbc-trt", "\n[drives.B]\n", "\n[drives.A]\n", r"\[drives\] B: missing key"),
    ("linuxcnc-xyzbc-trt", "B = { kp = 736.64", "A = { kp = 736.64",
     r"\[controllers.pid-high\] B: missing key"),
    ("linuxcnc-xyzac-trt", "p_max = 200", "p_max = -300",
     r"\[drives.X\] p_max: must be > p_min \(-200\), got -300"),
])
def test_trunnion_machine_file_errors(tmp_path, machine_name, old, new, pattern):
    path = tmp_path / "trt.toml"
    path.write_text(_edit(builtin_machine_text(machine_name), old, new))
    with pytest.raises(MachineFileError, match=pattern) as info:
        load_machine(path)
    assert str(info.value).startswith(str(path))
    assert "\n" not in str(info.value).strip()


@pytest.mark.parametrize("name, tilt_deg, c_deg", [
    # ranges of LinuxCNC's table-rotary-tilting demo programs (TCP mode, degrees):
    ("linuxcnc-xyzac-trt", (-74.49, 0.0), (-399.805, 0.0)),      # impeller-7bl-xyzac.ngc
    ("linuxcnc-xyzac-trt", (-75.001, 0.0), (-154.392, 270.0)),   # boat-xyzac.ngc
    ("linuxcnc-xyzbc-trt", (-75.001, 0.0), (-64.392, 360.0)),    # boat-xyzbc.ngc
])
def test_linuxcnc_demo_programs_fit_the_travel(name, tilt_deg, c_deg):
    machine = load_machine(name)
    tilt, c = machine.drives[3], machine.drives[4]
    assert tilt.p_min < np.radians(tilt_deg[0]) and np.radians(tilt_deg[1]) < tilt.p_max
    assert c.p_min < np.radians(c_deg[0]) and np.radians(c_deg[1]) < c.p_max
    # the programs' tool tips span about x -50..50, y -45..45, z -14..40 mm in the workpiece
    # frame: every corner of that box at every tilt and turn of the programs stays inside
    # the linear travel
    corners = np.array(np.meshgrid([-50, 50], [-45, 45], [-14, 40])).reshape(3, -1).T
    rotary = np.radians(np.array(np.meshgrid(np.linspace(*tilt_deg, 16),
                                             np.linspace(-180, 180, 37))).reshape(2, -1).T)
    xyz = machine.kinematics.linear_axes(corners[:, None, :], rotary[None, :, 0],
                                         rotary[None, :, 1])
    for i, drive in enumerate(machine.drives[:3]):
        assert drive.p_min < xyz[..., i].min() and xyz[..., i].max() < drive.p_max


def test_machine_file_text_round_trips_the_builtin_machine():
    from precontour.machine.machine_file import machine_data, machine_file_text

    data, _ = machine_data("zhang2013")
    again = parse_machine(machine_file_text(data, "a header\nof two lines"))
    original = load_machine("zhang2013")
    assert again.drives == original.drives
    assert again.kinematics == original.kinematics
    assert dict(again.controllers) == dict(original.controllers)


TF_MACHINE = """
[controllers.fit]
type = "tf"
X = {{ num = {num}, den = {den} }}
Y = {{ num = [1.0], den = [0.01, 1.0] }}
Z = {{ num = [1.0], den = [0.01, 1.0] }}
A = {{ num = [1.0], den = [0.01, 1.0] }}
C = {{ num = [1.0], den = [0.01, 1.0] }}
"""


def _tf_machine(num, den):
    from precontour.machine.machine_file import builtin_machine_text

    return parse_machine(builtin_machine_text() + TF_MACHINE.format(num=num, den=den))


def test_tf_controller_error_model_is_one_minus_the_loop():
    machine = _tf_machine("[300.0, 20000.0]", "[1.0, 300.0, 20000.0]")
    model = machine.error_models("fit")[0]
    np.testing.assert_allclose(model.num, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(model.den, [1.0, 300.0, 20000.0])


@pytest.mark.parametrize("num, den, message", [
    ("[1.0, 2.0, 3.0]", "[1.0, 3.0]", "must be proper"),
    ("[1.0]", "[1.0, -3.0]", "not stable"),
    ("[1.0]", "[0.0, 0.0]", "degree >= 1"),
    ("[1.0]", "[1.0]", "at least 2"),
    ("[\"a\"]", "[1.0, 3.0]", "finite numbers"),
])
def test_tf_controller_errors_name_the_key(num, den, message):
    with pytest.raises(MachineFileError, match=rf"\[controllers\.fit\.X\] (num|den): .*{message}"):
        _tf_machine(num, den)
