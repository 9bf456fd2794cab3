"""LinuxCNC's interpreter as the reference for the G-code reader: its canonical moves, and
precontour's programmed moves compared with them.

Two views of the same interpreter (LinuxCNC 2.9's rs274ngc):

- :func:`canonical_moves` runs ``linuxcnc_reference.py`` under the system Python that has
  LinuxCNC's ``gcode`` module: every STRAIGHT_TRAVERSE / STRAIGHT_FEED / ARC_FEED in double
  precision with its source line and feed rate;
- :func:`rs274_moves` runs the ``rs274`` program and parses its printout (4 decimals, in the
  program's units), a check of the first on the unchanged program (tool words included).

:func:`compare` matches them move by move with a program read by precontour.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from precontour.machine.machine_file import load_machine

HERE = Path(__file__).parent
DATA = HERE / "data"
NCFILES = Path("/usr/share/linuxcnc/ncfiles")
DEMOS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
             "table-rotary-tilting/demos")
SYSTEM_PYTHON = "/usr/bin/python3"
#: Test programs in dialects LinuxCNC does not read (checked by hand in test_gcode.py).
NOT_LINUXCNC = {"data/fanuc_trunnion.nc": "Fanuc's G43.4 and G68.2, which LinuxCNC does not read",
                "data/haas_fusion_umc750.nc": "Haas's G234 and G254, which LinuxCNC does not read",
                "data/haas_nx_umc750.nc": "Haas's G234 and G254, which LinuxCNC does not read"}
INCH = 25.4
#: LinuxCNC's axis slots X Y Z A B C.
SLOTS = {"X": 0, "Y": 1, "Z": 2, "A": 3, "B": 4, "C": 5}


_B_WORD = re.compile(r"(?<![A-Z#<_\[])B\s*[-+.\d#\[]")
_COMMENTS = re.compile(r"\([^)]*\)|;.*")


def programs():
    """The test data's programs and LinuxCNC's installed examples (those present)."""
    found = sorted(p for pattern in ("*.ngc", "*.nc") for p in DATA.glob(pattern))
    if NCFILES.is_dir():
        found += sorted(NCFILES.rglob("*.ngc"))
    if DEMOS.is_dir():
        found += sorted(DEMOS.glob("*.ngc"))
    return found


def program_key(path: Path) -> str:
    """A program's name: its path in ncfiles, or folder/name."""
    if NCFILES in path.parents:
        return str(path.relative_to(NCFILES))
    return f"{path.parent.name}/{path.name}"


def program_machine(path: Path):
    """The LinuxCNC trunnion simulator the program is for: B-C if it names B, else A-C
    (the Haas programs: their UMC-750 machine file, data/haas-umc750.toml)."""
    if path.name.startswith("haas_"):
        return load_machine(DATA / "haas-umc750.toml")
    text = _COMMENTS.sub("", path.read_text(errors="replace").upper())
    name = "linuxcnc-xyzbc-trt" if "xyzbc" in path.name or _B_WORD.search(text) else \
        "linuxcnc-xyzac-trt"
    return load_machine(name)


def linuxcnc_missing() -> str | None:
    """Why the reference cannot run here (None if it can)."""
    if shutil.which("rs274") is None:
        return "LinuxCNC's rs274 is not installed"
    if not Path(SYSTEM_PYTHON).exists():
        return f"{SYSTEM_PYTHON} (the Python LinuxCNC's gcode module is built for) is missing"
    check = subprocess.run([SYSTEM_PYTHON, "-c", "import gcode"], capture_output=True)
    if check.returncode != 0:
        return "LinuxCNC's gcode module is not importable by " + SYSTEM_PYTHON
    return None


def remap_ini(folder: Path, on="M428", off="M429") -> Path:
    """An INI file that remaps the TCP switches to empty subroutines (what the canonical
    moves see of them: nothing; LinuxCNC's sim configurations switch kinematics there)."""
    subs = folder / "remap_subs"
    subs.mkdir(exist_ok=True)
    for name in ("tcp_on", "tcp_off"):
        (subs / f"{name}.ngc").write_text(f"o<{name}> sub\no<{name}> endsub\n")
    ini = folder / "remap.ini"
    ini.write_text("[RS274NGC]\n"
                   f"PARAMETER_FILE = {folder / 'linuxcnc.var'}\n"
                   f"SUBROUTINE_PATH = {subs}\n"
                   f"REMAP = {on} modalgroup=10 ngc=tcp_on\n"
                   f"REMAP = {off} modalgroup=10 ngc=tcp_off\n")
    return ini


def canonical_moves(path: Path, ini: Path | None = None) -> dict:
    """LinuxCNC's canonical moves of ``path`` (see ``linuxcnc_reference.py``)."""
    args = [SYSTEM_PYTHON, str(HERE / "linuxcnc_reference.py"), str(path)]
    if ini is not None:
        args.append(str(ini))
    done = subprocess.run(args, capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise RuntimeError(f"linuxcnc_reference.py failed on {path}: {done.stderr[-500:]}")
    return json.loads(done.stdout.replace("NaN", "null"))


_CALL = re.compile(r"^\s*\d+ N\S*\s+([A-Z0-9_]+)\((.*)\)\s*$")


def rs274_moves(path: Path, ini: Path | None = None) -> list[dict]:
    """The moves of ``rs274``'s printout (absolute, mm and degrees, 4 decimals)."""
    with tempfile.TemporaryDirectory() as folder:
        # tools 1-99 of zero length in pockets 1-99 (G43 Hn needs the tool in the table)
        tools = Path(folder) / "tools.tbl"
        tools.write_text("".join(f"T{n} P{n} Z0 D0\n" for n in range(1, 100)))
        args = ["rs274", "-g", "-t", str(tools)]
        if ini is not None:
            # a fresh parameter file: rs274 writes G10's offsets back into it at the end
            text = re.sub(r"(?m)^PARAMETER_FILE\s*=.*$",
                          f"PARAMETER_FILE = {Path(folder) / 'rs274.var'}", ini.read_text())
            ini = Path(folder) / "rs274.ini"
            ini.write_text(text)
            args += ["-i", str(ini)]
        done = subprocess.run(args + [str(Path(path).resolve())], capture_output=True, text=True,
                              stdin=subprocess.DEVNULL, timeout=600, cwd=folder)
    moves, scale = [], 1.0
    g5x, g92, rotation, plane = [0.0] * 6, [0.0] * 6, 0.0, "XY"
    for line in done.stdout.splitlines():
        match = _CALL.match(line)
        if match is None:
            continue
        name, args_text = match.groups()
        if name == "USE_LENGTH_UNITS":
            scale = INCH if "INCHES" in args_text else 1.0
            continue
        if name == "SELECT_PLANE":
            plane = args_text.split("_")[-1]
            continue
        if name not in ("SET_G5X_OFFSET", "SET_G92_OFFSET", "SET_XY_ROTATION",
                        "STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED"):
            continue
        values = [float(v) for v in re.split(r"[,\s]+", args_text.strip()) if v]
        if name == "SET_G5X_OFFSET":
            g5x = [v * (scale if i < 3 else 1.0) for i, v in enumerate(values[1:7])]
        elif name == "SET_G92_OFFSET":
            g92 = [v * (scale if i < 3 else 1.0) for i, v in enumerate(values[:6])]
        elif name == "SET_XY_ROTATION":
            rotation = values[0]
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            p = [v * (scale if i < 3 else 1.0) for i, v in enumerate(values[:6])]
            moves.append(dict(kind="traverse" if name == "STRAIGHT_TRAVERSE" else "feed",
                              end=_absolute(p, g5x, g92, rotation)))
        elif name == "ARC_FEED":
            first, second, c1, c2, turn, normal = values[:6]
            order = {"XY": (0, 1, 2), "YZ": (1, 2, 0), "XZ": (2, 0, 1)}[plane]
            p = [0.0] * 6
            p[order[0]], p[order[1]], p[order[2]] = first * scale, second * scale, normal * scale
            p[3:6] = values[6:9]
            moves.append(dict(kind="arc", end=_absolute(p, g5x, g92, rotation),
                              rotation=int(turn)))
    return moves


def _absolute(p, g5x, g92, rotation):
    p = [v + o for v, o in zip(p, g92)]
    if rotation:
        t = math.radians(rotation)
        p[0], p[1] = (p[0] * math.cos(t) - p[1] * math.sin(t),
                      p[0] * math.sin(t) + p[1] * math.cos(t))
    return [v + o for v, o in zip(p, g5x)]


@dataclass
class Comparison:
    """What :func:`compare` checked: moves compared, largest differences."""

    n_moves: int
    n_arcs: int
    end: float           # mm (deg on rotary axes)
    centre: float        # mm
    rate: float          # relative
    rs274: float         # mm, the 4-decimal printout against the double-precision moves
    stopped_at: int | None = None   # line of the first TCP switch after the start, if any
    n_dwells: int = 0


def _length(start, end):
    """LinuxCNC's length of a straight move for its feed: XYZ if they move, else ABC."""
    d = np.linalg.norm(end[:3] - start[:3])
    return d if d > 0 else np.linalg.norm(end[3:] - start[3:])


def compare(program, machine, reference: dict, rs274: list[dict] | None = None
            ) -> Comparison:
    """Compare precontour's programmed moves with LinuxCNC's canonical moves (absolute,
    mm and degrees; the machine's axis letters picked from LinuxCNC's six slots). The moves
    before the program's start (positioning with axes not yet known) are left out; from the
    first TCP switch after the start on, the two differ by design (LinuxCNC's stand-alone
    interpreter keeps the programmed point where the machine re-reads it through the
    kinematics; precontour's G53 in TCP mode is a joint move) and are not compared."""
    moves = reference["moves"]
    slots = [SLOTS[a] for a in program.axes]
    pm = program.programmed
    # LinuxCNC's first moves position the axes before precontour's start (the block that
    # makes every axis known): precontour keeps the moves after it
    k0 = len(moves) - pm.n_moves
    assert k0 >= 0, (f"{program.source}: LinuxCNC has {len(moves)} moves, precontour "
                     f"{pm.n_moves} after its start")
    assert all(m["kind"] == "traverse" for m in moves[:max(k0 - 1, 0)]), (
        f"{program.source}: LinuxCNC feeds before precontour's start (line "
        f"{program.start_line}): {[m['line'] for m in moves[:k0] if m['kind'] != 'traverse']}")
    ref = moves[k0:]
    start_ref = np.array(moves[k0 - 1]["end"])[slots] if k0 else None
    stopped_at = None
    n = pm.n_moves
    switch = np.flatnonzero(pm.tcp != pm.tcp[0]) if n else []
    if len(switch):
        n = int(switch[0])
        stopped_at = int(pm.line[n])
    kinds = {"traverse": 0, "feed": 1, "arc": 2}
    worst_end = worst_centre = worst_rate = 0.0
    n_arcs = 0
    # precontour's start in the frame of its first move (the tool tip for a TCP move)
    prev = program.start.copy()
    if n and pm.tcp[0]:
        prev[:3] = machine.kinematics.forward(program.start)[0]
    prev[3:] = np.degrees(prev[3:])
    if start_ref is not None:
        np.testing.assert_allclose(start_ref, prev, rtol=0, atol=1e-6,
                                   err_msg=f"{program.source}: the start position")
    for k in range(n):
        r = ref[k]
        where = f"{program.source}, line {pm.line[k]} (move {k})"
        assert kinds[r["kind"]] == pm.kind[k], f"{where}: {r['kind']} vs kind {pm.kind[k]}"
        assert r["line"] == pm.line[k], f"{where}: LinuxCNC's line {r['line']}"
        end_ref = np.array(r["end"])[slots]
        d = np.abs(end_ref - pm.end[k])
        worst_end = max(worst_end, float(d.max()))
        assert d.max() <= 1e-6, f"{where}: end {pm.end[k].tolist()} vs {end_ref.tolist()}"
        if r["kind"] == "arc":
            n_arcs += 1
            plane_axes = {17: (0, 1), 18: (2, 0), 19: (1, 2)}[r["plane"]]
            assert r["plane"] == pm.plane[k], f"{where}: plane {r['plane']} vs {pm.plane[k]}"
            assert r["rotation"] == pm.turns[k], f"{where}: turns {r['rotation']} vs {pm.turns[k]}"
            c = np.array([np.nan if v is None else v for v in r["centre"]])
            dc = np.abs(c[list(plane_axes)] - pm.centre[k][list(plane_axes)])
            worst_centre = max(worst_centre, float(dc.max()))
            assert dc.max() <= 1e-6, f"{where}: centre {pm.centre[k]} vs {c}"
        if r["kind"] != "traverse":
            # the canonical feed rate: F in G94; the length times F in G93 (LinuxCNC's
            # inverse-time rate, at least 0.1 units/min)
            rate_ref = r["rate"] * INCH
            if r["kind"] == "arc":
                length = _arc_length(prev, pm.end[k], pm.centre[k], pm.plane[k], pm.turns[k])
            else:
                length = _length(prev, pm.end[k])
            rotary_only = (r["kind"] == "feed" and np.linalg.norm(pm.end[k][:3] - prev[:3]) == 0
                           and np.linalg.norm(pm.end[k][3:] - prev[3:]) > 0)
            if rotary_only and r.get("inch"):
                rate_ref /= INCH
            if pm.inverse_time[k]:
                unit = INCH if r.get("inch") and not rotary_only else 1.0
                rate = max(0.1, length / unit * pm.feed[k]) * unit
            else:
                rate = pm.feed[k]
            if not (length == 0 and pm.inverse_time[k]):
                rel = abs(rate - rate_ref) / max(abs(rate_ref), 1e-12)
                worst_rate = max(worst_rate, rel)
                assert rel <= 1e-9, f"{where}: feed rate {rate} vs LinuxCNC's {rate_ref}"
        prev = pm.end[k]
    # the dwells (G4, canned cycles) after the same moves, for the same time
    dwells = [(d["after"] - k0, d["seconds"]) for d in reference.get("dwells", [])
              if d["after"] >= k0 and (stopped_at is None or d["after"] - k0 <= n)]
    ours = [(s.index, s.seconds) for s in program.stops if s.kind == "dwell"
            and s.index >= 0 and (s.index > 0 or s.line >= program.start_line)
            and (stopped_at is None or s.index <= n)]
    assert [d[0] for d in ours] == [d[0] for d in dwells], (
        f"{program.source}: dwells after moves {[d[0] for d in ours]}, LinuxCNC's after "
        f"{[d[0] for d in dwells]}")
    np.testing.assert_allclose([d[1] for d in ours], [d[1] for d in dwells], rtol=1e-12,
                               err_msg=f"{program.source}: dwell times")
    worst_rs274 = 0.0
    if rs274 is not None:
        assert len(rs274) == len(moves), (f"{program.source}: rs274 prints {len(rs274)} moves, "
                                          f"the gcode module gives {len(moves)}")
        for a, b in zip(rs274, moves):
            d = float(np.max(np.abs(np.array(a["end"]) - np.array(b["end"]))))
            worst_rs274 = max(worst_rs274, d)
        # 4 decimals in the program's units (inches: 2.54 um)
        assert worst_rs274 <= 0.5e-4 * INCH + 1e-9, f"{program.source}: rs274 {worst_rs274}"
    return Comparison(n, n_arcs, worst_end, worst_centre, worst_rate, worst_rs274, stopped_at,
                      len(ours))


def _arc_length(start, end, centre, plane, turns):
    """LinuxCNC's arc length for the feed: the helix in the plane and its normal axis."""
    a, b, n = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}[int(plane)]
    r0 = math.hypot(start[a] - centre[a], start[b] - centre[b])
    alpha = math.atan2(start[b] - centre[b], start[a] - centre[a])
    beta = math.atan2(end[b] - centre[b], end[a] - centre[a])
    # LinuxCNC's find_turn: a full circle (beta == alpha) of one turn counts 0, so its G93
    # rate is the 0.1 units/min floor
    if turns > 0:
        if beta < alpha:
            beta += 2 * math.pi
        sweep = beta - alpha + (turns - 1) * 2 * math.pi
    else:
        if alpha < beta:
            alpha += 2 * math.pi
        sweep = beta - alpha + (turns + 1) * 2 * math.pi
    return math.hypot(r0 * sweep, end[n] - start[n])
