"""The LinuxCNC configuration ``precontour linuxcnc-config`` writes (text only; tests/linuxcnc
starts LinuxCNC from it)."""

from __future__ import annotations

import configparser
import math

import pytest

from precontour import load_machine
from precontour.cli import main
from precontour.errors import InputError, OutputError
from precontour.machine.machine_file import machine_data, machine_file_text, parse_machine
from precontour.linuxcnc.config import HEADER, linuxcnc_config, write_linuxcnc_config


def _ini(text: str) -> configparser.ConfigParser:
    parser = configparser.ConfigParser(strict=False, comment_prefixes=("#", ";"),
                                       inline_comment_prefixes=None)
    parser.optionxform = str
    parser.read_string(text)
    return parser


@pytest.mark.parametrize("name", ["zhang2013", "linuxcnc-xyzac-trt", "linuxcnc-xyzbc-trt"])
def test_limits_are_the_machine_files_in_degrees(name):
    machine = load_machine(name)
    config = linuxcnc_config(machine)
    for ini_name in ("machine.ini", "headless.ini"):
        ini = _ini(config.files[ini_name])
        assert ini["EMCMOT"]["SERVO_PERIOD"] == str(round(machine.servo_period * 1e9))
        assert ini["TRAJ"]["COORDINATES"] == " ".join(machine.axis_names)
        for n, (letter, drive) in enumerate(zip(machine.axis_names, machine.drives)):
            scale = 180 / math.pi if letter in "ABC" else 1.0
            for section in (f"AXIS_{letter}", f"JOINT_{n}"):
                values = ini[section]
                assert float(values["MAX_VELOCITY"]) == pytest.approx(drive.v_max * scale,
                                                                      rel=1e-11)
                assert float(values["MAX_ACCELERATION"]) == pytest.approx(
                    drive.a_max * scale, rel=1e-11)
                if drive.p_min is None:
                    assert "MIN_LIMIT" not in values
                else:
                    assert float(values["MIN_LIMIT"]) == pytest.approx(drive.p_min * scale,
                                                                       rel=1e-11)
                    assert float(values["MAX_LIMIT"]) == pytest.approx(drive.p_max * scale,
                                                                       rel=1e-11)
            assert ini[f"JOINT_{n}"]["TYPE"] == ("ANGULAR" if letter in "ABC" else "LINEAR")


def test_xyzac_trt_travel_in_degrees_is_the_simulators():
    # LinuxCNC's sim: A -100 .. 50 deg, C +-36000 deg (the machine file holds them in rad)
    ini = _ini(linuxcnc_config(load_machine("linuxcnc-xyzac-trt")).files["machine.ini"])
    assert float(ini["AXIS_A"]["MIN_LIMIT"]) == pytest.approx(-100.0, rel=1e-12)
    assert float(ini["AXIS_A"]["MAX_LIMIT"]) == pytest.approx(50.0, rel=1e-12)
    assert float(ini["AXIS_C"]["MAX_LIMIT"]) == pytest.approx(36000.0, rel=1e-12)
    assert float(ini["AXIS_A"]["MAX_VELOCITY"]) == pytest.approx(30.0, rel=1e-12)


def test_kinematics_module_and_offsets():
    zhang = linuxcnc_config(load_machine("zhang2013"))
    assert zhang.kinematics == "trivkins" and not zhang.tcp
    assert "KINEMATICS = trivkins coordinates=XYZAC" in zhang.files["machine.ini"]
    assert "remap/428remap.ngc" not in zhang.files

    ac = linuxcnc_config(load_machine("linuxcnc-xyzac-trt"))
    assert ac.kinematics == "xyzac-trt-kins" and ac.tcp
    ini = ac.files["machine.ini"]
    assert "KINEMATICS = xyzac-trt-kins coordinates=XYZAC sparm=identityfirst" in ini
    assert "REMAP = M428 modalgroup=10 ngc=428remap" in ini
    hal = ac.files["machine.hal"]
    for line in ("setp xyzac-trt-kins.y-offset 20", "setp xyzac-trt-kins.z-offset 10",
                 "setp xyzac-trt-kins.x-rot-point 0",
                 "net :tool-offset motion.tooloffset.z => xyzac-trt-kins.tool-offset",
                 "net :kinstype-select motion.analog-out-03 => motion.switchkins-type"):
        assert line in hal
    assert "conventional-directions" not in hal  # directions -1: LinuxCNC 2.9's only sense
    assert "M68 E3 Q1" in ac.files["remap/428remap.ngc"]
    assert "M68 E3 Q0" in ac.files["remap/429remap.ngc"]

    bc = linuxcnc_config(load_machine("linuxcnc-xyzbc-trt"))
    assert "setp xyzbc-trt-kins.x-offset -20" in bc.files["machine.hal"]
    assert "setp xyzbc-trt-kins.z-offset -15" in bc.files["machine.hal"]
    assert "KINEMATICS = xyzbc-trt-kins coordinates=XYZBC" in bc.files["machine.ini"]
    assert "net b-world axis.b.pos-cmd" in bc.files["record.hal"]


def _variant(name: str, kinematics: dict):
    data, _ = machine_data(name)
    data["kinematics"].update(kinematics)
    return parse_machine(machine_file_text(data), source="<variant>")


def test_conventional_directions_need_linuxcnc_2_10_and_mixed_ones_are_refused():
    both = _variant("linuxcnc-xyzac-trt", {"a_direction": 1, "c_direction": 1})
    assert ("setp xyzac-trt-kins.conventional-directions 1"
            in linuxcnc_config(both).files["machine.hal"])
    mixed = _variant("linuxcnc-xyzac-trt", {"a_direction": 1})
    with pytest.raises(InputError, match="same way"):
        linuxcnc_config(mixed)


def test_streamer_and_recorder_sized_for_the_servo_period():
    config = linuxcnc_config(load_machine("zhang2013"))
    stream = config.files["stream.hal"]
    assert "loadrt threads name1=servo-thread period1=1000000" in stream
    assert "loadrt streamer depth=2000 cfg=fffff" in stream
    assert "addf streamer.0 servo-thread" in stream
    record = config.files["record.hal"]
    assert "cfg=ffffffffffss" in record and "motion.program-line => sampler.0.pin.10" in record


def test_folder_written_as_a_set_replaced_only_when_ours(tmp_path):
    machine = load_machine("linuxcnc-xyzac-trt")
    target = tmp_path / "cfg"
    files = write_linuxcnc_config(machine, target)
    assert all(p.is_file() for p in files) and len(files) == 9
    assert (target / "machine.ini").read_text().startswith(HEADER)
    assert (target / "headless.py").stat().st_mode & 0o111
    assert (target / "remap" / "428remap.ngc").is_file()
    (target / "linuxcnc.var").write_text("5161 0\n")  # LinuxCNC's own file, written on a run
    write_linuxcnc_config(load_machine("zhang2013"), target)
    assert "trivkins" in (target / "machine.ini").read_text()
    assert not (target / "remap").exists() and not (target / "linuxcnc.var").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["cfg"]  # no staging folder left

    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="other contents"):
        write_linuxcnc_config(machine, other)
    assert (other / "notes.txt").read_text() == "mine"
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="not a folder"):
        write_linuxcnc_config(machine, tmp_path / "file")
    with pytest.raises(OutputError, match="parent does not exist"):
        write_linuxcnc_config(machine, tmp_path / "missing" / "cfg")


def test_machine_without_limits_is_refused():
    data, _ = machine_data("zhang2013")
    del data["drives"]["A"]["a_max"]
    del data["drives"]["A"]["j_max"]
    machine = parse_machine(machine_file_text(data), source="m.toml")
    with pytest.raises(InputError, match="axis A has no a_max"):
        linuxcnc_config(machine)


def test_cli(tmp_path, capsys):
    assert main(["linuxcnc-config", "--machine", "linuxcnc-xyzbc-trt", "-o",
                 str(tmp_path / "cfg")]) == 0
    out = capsys.readouterr().out
    assert "LinuxCNC configuration for linuxcnc-xyzbc-trt" in out
    assert (tmp_path / "cfg" / "stream.hal").is_file()
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "x").write_text("")
    assert main(["linuxcnc-config", "--machine", "zhang2013", "-o", str(tmp_path / "busy")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("precontour: error: ") and "busy" in err and err.count("\n") == 1
    assert main(["linuxcnc-config", "--machine", "nosuch", "-o", str(tmp_path / "c")]) == 2
    assert not (tmp_path / "c").exists()


def _setp(hal: str) -> dict[str, float]:
    """The ``setp NAME VALUE`` lines of a HAL file."""
    values = {}
    for line in hal.splitlines():
        words = line.split()
        if len(words) >= 3 and words[0] == "setp":
            values[words[1]] = float(words[2])
    return values


@pytest.mark.parametrize("name", ["zhang2013", "linuxcnc-xyzbc-trt", "linuxcnc-bridgemill"])
def test_simulated_drives_run_the_controllers_gains_around_the_drives(name):
    """pid per joint unit (degrees on rotary joints) and the plant of spec section 2 from
    the machine file, checked against the machine file's numbers directly."""
    machine = load_machine(name)
    config = linuxcnc_config(machine, drives="simulated", controller="pid-high")
    hal = config.files["machine.hal"]
    setp = _setp(hal)
    gains = machine.controller("pid-high").axes
    for n, (letter, drive, pid) in enumerate(zip(machine.axis_names, machine.drives, gains)):
        unit = math.pi / 180 if letter in "ABC" else 1.0
        name_ = letter.lower()
        assert setp[f"pid.{name_}.Pgain"] == pytest.approx(pid.kp * unit, rel=1e-11)
        assert setp[f"pid.{name_}.Igain"] == pytest.approx(pid.ki * unit, rel=1e-11)
        assert setp[f"pid.{name_}.Dgain"] == pytest.approx(pid.kd * unit, rel=1e-11)
        assert setp[f"drive-{name_}-net.gain0"] == pytest.approx(drive.ka * drive.kt, rel=1e-11)
        assert setp[f"drive-{name_}-net.gain1"] == pytest.approx(-drive.B, rel=1e-11)
        assert setp[f"drive-{name_}-accel.gain0"] == pytest.approx(1 / drive.J, rel=1e-11)
        assert setp[f"drive-{name_}-rate.gain"] == pytest.approx(drive.rg / unit, rel=1e-11)
        assert setp[f"drive-{name_}-friction.max"] == pytest.approx(drive.friction.Tc_pos)
        assert setp[f"drive-{name_}-friction.min"] == pytest.approx(drive.friction.Tc_neg)
        # motion -> overlay offset -> pid; plant -> pid and, less the offset, -> motion
        assert f"net j{n}-cmd joint.{n}.motor-pos-cmd => overlay-{name_}.in" in hal
        assert f"net j{n}-overlaid overlay-{name_}.out => pid.{name_}.command" in hal
        assert f"net j{n}-overlay streamer.0.pin.{n} => overlay-{name_}.offset" in hal
        assert (f"net j{n}-pos drive-{name_}-pos.out => pid.{name_}.feedback "
                f"overlay-{name_}.fb-in") in hal
        assert f"net j{n}-fb overlay-{name_}.fb-out => joint.{n}.motor-pos-fb" in hal
        assert f"net j{n}-pos joint.{n}.motor-pos-cmd => joint.{n}.motor-pos-fb" not in hal
    # every component loads once (a second loadrt of one would fail at start-up)
    loaded = [line.split()[1] for line in hal.splitlines() if line.startswith("loadrt ")]
    assert len(loaded) == len(set(loaded))
    ini = _ini(config.files["headless.ini"])
    assert float(ini["JOINT_0"]["FERROR"]) > 0 and float(ini["JOINT_0"]["MIN_FERROR"]) > 0
    assert "net overlay-enable motion.digital-out-00 => streamer.0.enable" in hal
    record = config.files["record.hal"]
    assert "j0 j1 j2 j3 j4 line a0 a1 a2 a3 a4 o0 o1 o2 o3 o4" in record
    assert "net j0-pos => sampler.0.pin.6" in record
    assert "net j4-overlay => sampler.0.pin.15" in record


def test_simulated_drives_need_a_pid_controller(tmp_path, capsys):
    machine = load_machine("zhang2013")
    with pytest.raises(InputError, match="pid"):
        linuxcnc_config(machine, drives="simulated", controller="p-pi-high")
    with pytest.raises(InputError, match="controller"):
        linuxcnc_config(machine, drives="simulated")
    assert main(["linuxcnc-config", "--machine", "zhang2013", "--drives", "simulated",
                 "-o", str(tmp_path / "cfg")]) != 0
    assert "--controller" in capsys.readouterr().err
    # the looped-back configuration is as before: no pid, no FERROR
    looped = linuxcnc_config(machine)
    assert "pid" not in looped.files["machine.hal"].replace("pid.0.command", "")
    assert "FERROR" not in looped.files["machine.ini"]


@pytest.mark.parametrize("former, module", [("linuxcnc", "config"), ("linuxcnc_run", "run"),
                                            ("linuxcnc_drives", "drives")])
def test_the_former_module_paths_warn_and_give_the_moved_modules(former, module):
    import importlib
    import sys

    sys.modules.pop(f"precontour.toolpath.{former}", None)
    with pytest.warns(DeprecationWarning, match=rf"precontour\.toolpath\.{former} is now "
                                                rf"precontour\.linuxcnc\.{module}; the former "
                                                r"path is removed in precontour 0\.2\.0"):
        old = importlib.import_module(f"precontour.toolpath.{former}")
    assert old is importlib.import_module(f"precontour.linuxcnc.{module}")
