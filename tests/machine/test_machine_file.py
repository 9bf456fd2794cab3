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
    high = np.sort(machine.controller("pid-high").error_models(machine.drives)[0].poles.real)
    low = np.sort(machine.controller("pid-low").error_models(machine.drives)[0].poles.real)
    np.testing.assert_allclose(high, [-187.6, -58.8, -42.0], atol=0.05)
    np.testing.assert_allclose(low, [-178.3, -32.7, -6.1], atol=0.05)


def test_bandwidths_match_paper(machine):
    from scipy import signal
    # measured: 53.4-55.9 Hz and 35.9-38.6 Hz (rotary axes lowest); paper: 55.8 and 38.6 Hz
    for name, lo, hi in (("pid-high", 53.2, 56.2), ("pid-low", 35.7, 38.9)):
        for model, drive in zip(machine.controller(name).error_models(machine.drives),
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
])
def test_machine_file_errors(tmp_path, old, new, pattern):
    path = tmp_path / "bad.toml"
    path.write_text(_edit(builtin_machine_text(), old, new))
    with pytest.raises(MachineFileError, match=pattern) as info:
        load_machine(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value).strip()


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
        m.controller("pid-high").error_models(m.drives)


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
    model = machine.controller("fit").error_models(machine.drives)[0]
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
