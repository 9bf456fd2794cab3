"""Annotated machine files (``precontour machines --template TYPE``): each loads back as the
built-in machine it was made from, names every key the loader reads, and the listing of the
built-in machines agrees with what the loader makes of them."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys

import pytest

from precontour.cli import main
from precontour.defaults import BUILTIN_MACHINES, builtin_machines
from precontour.machine import KINEMATICS_TYPES, load_machine, parse_machine
from precontour.machine._config import ConfigTable
from precontour.machine.controllers import CONTROLLER_TYPES
from precontour.machine.template import (CONTROLLER_KEYS, KINEMATICS_KEYS, machine_template,
                                         template_types)

BUILTIN_OF_TYPE = {"ac-trunnion": "zhang2013", "xyzac-trt": "linuxcnc-xyzac-trt",
                   "xyzbc-trt": "linuxcnc-xyzbc-trt", "xyzbc-head-table": "head-table-bc",
                   "xyzbc-head-head": "linuxcnc-bridgemill", "chain": "head-table-ac"}


def test_every_kinematics_and_controller_type_is_described():
    assert set(template_types()) == set(KINEMATICS_TYPES) == set(KINEMATICS_KEYS)
    assert set(CONTROLLER_KEYS) == set(CONTROLLER_TYPES)


@pytest.mark.parametrize("kind", sorted(BUILTIN_OF_TYPE))
def test_template_printed_by_the_cli_loads_back_as_the_builtin_machine(kind, capsys):
    assert main(["machines", "--template", kind]) == 0
    text = capsys.readouterr().out
    loaded = parse_machine(text, source="template")
    builtin = load_machine(BUILTIN_OF_TYPE[kind])
    assert type(loaded.kinematics).__name__ == type(builtin.kinematics).__name__
    assert dataclasses.replace(loaded, source="") == dataclasses.replace(builtin, source="")
    assert loaded.axis_names == builtin.axis_names
    # every line is a comment, a table header, a key = value or blank, and fits 99 columns
    for line in text.splitlines():
        assert len(line) <= 99, line
        assert re.match(r"^(#.*|\[[\w.-]+\]|[\w-]+ = .+|)$", line), line


@pytest.mark.parametrize("kind", sorted(BUILTIN_OF_TYPE))
def test_template_names_every_key_the_loader_reads(kind, monkeypatch):
    """Every key the loader asks for (given or not: optional keys are asked for with their
    default) appears in the template, as an entry or a commented-out one, with a comment."""
    asked = set()
    original = ConfigTable._get

    def recording(self, key, default):
        asked.add((self.path, key))
        return original(self, key, default)

    monkeypatch.setattr(ConfigTable, "_get", recording)
    text = machine_template(kind)
    parse_machine(text)
    assert len(asked) > 100
    entries, headers = {}, set()
    table = ""
    for line in text.splitlines():
        header = re.match(r"^\[([\w.-]+)\]$", line)
        if header:
            table = header.group(1)
            headers.add(table)
            continue
        if re.match(r"^# \[([\w.-]+)\]$", line):   # an optional table, commented out
            table = line[3:-1]
            headers.add(table)
            continue
        entry = re.match(r"^(?:# )?([\w-]+) = (.+?)(?:\s+# (.+))?$", line)
        if entry:
            entries[(table, entry.group(1))] = entry.group(3)
    comments = "\n".join(line for line in text.splitlines() if line.startswith("#"))
    for path, key in sorted(asked):
        full = f"{path}.{key}" if path else key
        if any(h == full or h.startswith(full + ".") for h in headers):
            continue  # a table
        parts = path.split(".")
        if parts[0] == "controllers" and len(parts) == 3:
            # per-axis gains are inline tables: their keys are described above the table
            assert re.search(rf"#\s+{re.escape(key)}: ", comments), (path, key)
            continue
        where = ".".join(parts[:2]) if parts[0] == "controllers" else path
        assert (where, key) in entries, (path, key)
        if key not in ("type",) and where.split(".")[0] != "controllers":
            described = entries[(where, key)] or _comment_above(text, where, key)
            assert described, (path, key)


@pytest.mark.parametrize("kind", sorted(BUILTIN_OF_TYPE))
def test_template_gcode_table_uncommented_loads_and_names_every_key(kind, monkeypatch):
    """The commented-out [gcode] table, uncommented, is a valid table: every key the loader
    reads is in it, and its values are what the loader makes of them."""
    text = machine_template(kind)
    entry = re.compile(r'^# (\[gcode(?:\.work_offsets)?\]|(?:[\w-]+|"[^"]+") = .+)$')
    lines = text.splitlines()
    block = [m.group(1) for line in lines[lines.index("# [gcode]"):]
             if (m := entry.match(line))]
    assert block[0] == "[gcode]" and "[gcode.work_offsets]" in block
    asked = set()
    original = ConfigTable._get

    def recording(self, key, default):
        asked.add((self.path, key))
        return original(self, key, default)

    monkeypatch.setattr(ConfigTable, "_get", recording)
    machine = parse_machine(text + "\n".join(block) + "\n", source="template")
    given = {re.match(r'^([\w-]+) = ', line).group(1) for line in block if "=" in line
             and not line.startswith('"')}
    assert {key for path, key in asked if path == "gcode"} - {"work_offsets"} <= given
    assert ("gcode", "work_offsets") in asked
    assert {"g28", "g30", "tcp_on", "tcp_off"} <= given
    settings = machine.gcode
    assert settings.g28 == settings.g30 == (0.0,) * 5
    assert (settings.tcp_on, settings.tcp_off) == ((428,), (429,))
    assert set(settings.work_offsets) == {"G54", "G59.1"}


def _comment_above(text, table, key):
    lines = text.splitlines()
    header = lines.index(f"[{table}]") if table else 0
    for i in range(header, len(lines)):
        if re.match(rf"^(# )?{re.escape(key)} = ", lines[i]):
            return lines[i - 1].startswith("#") and lines[i - 1]
    return None


def test_unknown_template_type_is_refused(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["machines", "--template", "hexapod"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert re.search(r"--template: invalid choice: 'hexapod' \(choose from .*ac-trunnion", err)


def test_machines_lists_what_the_loader_loads(capsys):
    assert main(["machines"]) == 0
    out = capsys.readouterr().out
    listed = builtin_machines()
    assert tuple(m.name for m in listed) == BUILTIN_MACHINES
    for entry in listed:
        machine = load_machine(entry.name)
        assert entry.axes == machine.axis_names
        assert entry.kinematics in KINEMATICS_TYPES
        assert isinstance(machine.kinematics, KINEMATICS_TYPES[entry.kinematics].__self__)
        assert entry.controllers == tuple((name, c.type) for name, c in
                                          machine.controllers.items())
        assert entry.servo_period == machine.servo_period
        assert entry.description == machine.description
        row = next(line for line in out.splitlines() if line.startswith(entry.name + " "))
        assert entry.kinematics in row and " ".join(machine.axis_names) in row
        for name in machine.controllers:
            assert re.search(rf"\b{re.escape(name)}\b", out)
    assert "--template TYPE" in out


def test_machines_is_light():
    """Listing the machines imports no numerical library."""
    code = ("import sys; from precontour.cli import main; main(['machines']); "
            "print(sorted(m for m in ('numpy', 'scipy', 'numba', 'matplotlib', 'pyarrow') "
            "if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[-1] == "[]"
