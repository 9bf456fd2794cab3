"""Run programs on LinuxCNC without a screen and record every servo period: how the tests and
``scripts/measure_linuxcnc.py`` check ``run``'s outputs with LinuxCNC itself.

:func:`run_gcode` starts LinuxCNC (``linuxcnc -r headless.ini`` of a configuration from
:func:`~precontour.linuxcnc.config.write_linuxcnc_config`: interpreter, task, planner,
motion controller), runs one program and returns the joint commands of every servo period
with the program line the planner executed. :func:`run_stream` runs ``stream.hal`` under
``halrun`` and feeds a ``run --stream`` file through ``halstreamer``. Without real-time rights
LinuxCNC's servo thread still runs once per servo period of wall time, and each recorded sample
is one period (``halsampler -t`` numbers them; a lost sample is reported as an overrun), so
the samples, not the wall clock, carry the timing.

LinuxCNC's ``rtapi_app`` refuses to run as root: as root, the run goes through ``runuser`` as
an unprivileged user (``user``, default ``$PRECONTOUR_LINUXCNC_USER`` or ``lcnc``), in a
private copy of the configuration that user may write. Only one LinuxCNC (or halrun session)
can run on a computer at a time: HAL's shared memory is the computer's.
"""

from __future__ import annotations

import os
import pwd
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import RECORD_COLUMNS, STREAM_COLUMNS

#: The unprivileged user LinuxCNC runs as when this process is root.
DEFAULT_USER = "lcnc"

__all__ = ["BlockTiming", "LinuxcncFailed", "LinuxcncUnavailable", "Recording",
           "block_timing", "linuxcnc_unavailable", "linuxcnc_user", "parse_run_gcode",
           "read_record", "run_gcode", "run_stream"]


class LinuxcncUnavailable(RuntimeError):
    """LinuxCNC cannot run here (not installed, or no user to run it as)."""


class LinuxcncFailed(RuntimeError):
    """LinuxCNC ran but did not complete the program; the message has its output's tail."""


@dataclass(frozen=True)
class Recording:
    """What the recorder saw, one row per servo period.

    Attributes
    ----------
    sample : ndarray of int, shape (N,)
        The sampler's period numbers (consecutive unless ``overruns``).
    ts : float
        Servo period, s.
    joints : ndarray, shape (N, 5)
        Joint position commands as LinuxCNC has them: mm, and degrees for rotary joints.
    columns : dict of str to ndarray
        Every recorded column (:data:`~precontour.linuxcnc.config.RECORD_COLUMNS` or
        :data:`~precontour.linuxcnc.config.STREAM_COLUMNS`) by name.
    overruns : int
        Samples the recorder lost (``halsampler`` could not keep up).
    log : str
        LinuxCNC's (or halrun's) output.
    """

    sample: np.ndarray
    ts: float
    joints: np.ndarray
    columns: dict
    overruns: int
    log: str = ""

    @property
    def t(self) -> np.ndarray:
        """Time of each sample from the first, s."""
        return (self.sample - self.sample[0]) * self.ts


def linuxcnc_user(user: str | None = None) -> str | None:
    """The user LinuxCNC runs as: None when this process is not root (it runs as itself)."""
    if os.geteuid() != 0:
        return None
    return user or os.environ.get("PRECONTOUR_LINUXCNC_USER") or DEFAULT_USER


def linuxcnc_unavailable(user: str | None = None) -> str | None:
    """Why LinuxCNC cannot run here, in one line, or None when it can."""
    for program in ("linuxcnc", "halrun", "halcmd", "halsampler", "halstreamer"):
        if shutil.which(program) is None:
            return (f"LinuxCNC is not installed ({program} not found; on Debian: apt-get "
                    "install linuxcnc-uspace)")
    if not Path("/usr/bin/python3").exists():
        return "no /usr/bin/python3 for LinuxCNC's linuxcnc module"
    probe = subprocess.run(["/usr/bin/python3", "-c", "import linuxcnc"], capture_output=True)
    if probe.returncode != 0:
        return "the system Python has no linuxcnc module (LinuxCNC's python3-linuxcnc)"
    name = linuxcnc_user(user)
    if name is not None:
        try:
            pwd.getpwnam(name)
        except KeyError:
            return (f"running as root, and LinuxCNC refuses root: no user {name!r} to run it "
                    "as (useradd it, or set PRECONTOUR_LINUXCNC_USER)")
        if shutil.which("runuser") is None:
            return "running as root and no runuser to run LinuxCNC as another user"
    if Path("/tmp/linuxcnc.lock").exists():
        return "another LinuxCNC is running here (/tmp/linuxcnc.lock)"
    return None


def _workspace(config: Path, user: str | None, files: dict[str, Path]) -> Path:
    """A private copy of ``config`` with ``files`` (name -> source) beside it, owned by
    ``user`` when given."""
    work = Path(tempfile.mkdtemp(prefix="precontour-linuxcnc-"))
    shutil.copytree(config, work / "config", symlinks=False)
    for name, source in files.items():
        shutil.copyfile(source, work / name)
    if user is not None:
        entry = pwd.getpwnam(user)
        for root, dirs, names in os.walk(work):
            for item in [root] + [os.path.join(root, n) for n in dirs + names]:
                os.chown(item, entry.pw_uid, entry.pw_gid)
    return work


def _as_user(user: str | None, env: dict[str, str], argv: list[str]) -> list[str]:
    assignments = [f"{key}={value}" for key, value in env.items()]
    prefix = ["runuser", "-u", user, "--"] if user is not None else []
    return prefix + ["env", "-u", "DISPLAY"] + assignments + argv


def _servo_period(config: Path) -> float:
    for line in (config / "machine.ini").read_text().splitlines():
        key, _, value = line.partition("=")
        if key.strip() == "SERVO_PERIOD":
            return int(value.strip()) * 1e-9
    raise ValueError(f"{config / 'machine.ini'}: no SERVO_PERIOD")


def _recorded_columns(config: Path) -> tuple[str, ...]:
    """The columns ``record.hal`` of ``config`` samples, from its ``# columns`` line (a
    configuration with simulated drives records the actual positions too)."""
    marker = "# columns after halsampler -t's sample number:"
    for line in (config / "record.hal").read_text().splitlines():
        if line.startswith(marker):
            return tuple(line[len(marker):].split())
    return RECORD_COLUMNS


def read_record(path: str | os.PathLike, columns: tuple[str, ...], ts: float,
                log: str = "") -> Recording:
    """A ``halsampler -t`` file: the sample number, then ``columns``, space-separated with a
    trailing space (lines reading ``overrun`` are counted and dropped)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    data = Path(path).read_bytes()
    overruns = data.count(b"overrun")
    if overruns:
        data = b"\n".join(line for line in data.split(b"\n") if b"overrun" not in line)
    names = ["sample", *columns, "_end"]
    if data.strip():
        table = pacsv.read_csv(pa.py_buffer(data),
                               read_options=pacsv.ReadOptions(column_names=names),
                               parse_options=pacsv.ParseOptions(delimiter=" "))
        by_name = {name: table.column(name).to_numpy() for name in names[:-1]}
    else:
        by_name = {name: np.zeros(0) for name in names[:-1]}
    sample = np.asarray(by_name.pop("sample"), dtype=np.int64)
    for name in ("line", "motion_type", "underruns", "depth"):
        if name in by_name:
            by_name[name] = np.asarray(by_name[name], dtype=np.int64)
    joints = np.column_stack([np.asarray(by_name[f"j{i}"], dtype=float) for i in range(5)])
    return Recording(sample=sample, ts=ts, joints=joints, columns=by_name, overruns=overruns,
                     log=log)


def run_gcode(config: str | os.PathLike, program: str | os.PathLike, *,
              user: str | None = None, timeout: float = 600.0,
              overlay: str | os.PathLike | None = None) -> Recording:
    """Run ``program`` on the configuration ``config`` (a folder of
    :func:`~precontour.linuxcnc.config.write_linuxcnc_config`) and record every servo
    period from before homing to after the program's end.

    ``overlay``: a file of ``run --overlay`` (a configuration with simulated drives), fed by
    ``halstreamer`` into the overlay streamer, which the program's ``M62 P0`` starts.

    Raises :class:`LinuxcncUnavailable` when LinuxCNC cannot run here and
    :class:`LinuxcncFailed` when the program did not run to its end (the message carries
    LinuxCNC's error)."""
    why = linuxcnc_unavailable(user)
    if why:
        raise LinuxcncUnavailable(why)
    config = Path(config)
    name = linuxcnc_user(user)
    files = {"program.ngc": Path(program)}
    if overlay is not None:
        files["overlay.txt"] = Path(overlay)
    work = _workspace(config, name, files)
    try:
        env = {"PRECONTOUR_PROGRAM": str(work / "program.ngc"),
               "PRECONTOUR_RECORD": str(work / "record.txt"),
               "PRECONTOUR_TIMEOUT": f"{timeout:g}", "HOME": str(work)}
        if overlay is not None:
            env["PRECONTOUR_OVERLAY"] = str(work / "overlay.txt")
        argv = _as_user(name, env, ["linuxcnc", "-r", str(work / "config" / "headless.ini")])
        try:
            done = subprocess.run(argv, cwd=work, capture_output=True, text=True,
                                  timeout=timeout + 60)
        except subprocess.TimeoutExpired as exc:
            raise LinuxcncFailed(f"LinuxCNC did not finish within {timeout + 60:g} s") from exc
        log = done.stdout + done.stderr
        if done.returncode != 0 or "headless: ran" not in log:
            raise LinuxcncFailed(f"LinuxCNC failed (exit {done.returncode}): "
                                 + " | ".join(log.strip().splitlines()[-8:]))
        return read_record(work / "record.txt", _recorded_columns(config),
                           _servo_period(config), log)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def run_stream(config: str | os.PathLike, stream: str | os.PathLike, *,
               user: str | None = None, timeout: float = 600.0) -> Recording:
    """Feed a ``run --stream`` file through ``halstreamer`` into ``stream.hal`` of
    ``config`` and record, from the first streamed sample on, one row per stream line: the
    five pins and the streamer's underrun count (``underruns`` column). The streamer and the
    recorder start in the same servo period, once the streamer's FIFO is full."""
    why = linuxcnc_unavailable(user)
    if why:
        raise LinuxcncUnavailable(why)
    config = Path(config)
    name = linuxcnc_user(user)
    n_lines = sum(1 for line in Path(stream).open() if line.strip() and not line.startswith("#"))
    work = _workspace(config, name, {"stream.txt": Path(stream)})
    env = {"HOME": str(work)}

    def hal(*args: str, check: bool = True) -> str:
        done = subprocess.run(_as_user(name, env, ["halcmd", *args]), capture_output=True,
                              text=True, timeout=30)
        if check and done.returncode != 0:
            raise LinuxcncFailed(f"halcmd {' '.join(args)}: {done.stderr.strip()}")
        return done.stdout

    session = streamer = sampler = None
    log = ""
    try:
        session = subprocess.Popen(_as_user(name, env, ["halrun", "-I", "-f",
                                                        str(work / "config" / "stream.hal")]),
                                   cwd=work / "config", stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        end = time.monotonic() + 30
        while "stream-enable" not in hal("show", "sig", "stream-enable", check=False):
            if time.monotonic() > end or session.poll() is not None:
                raise LinuxcncFailed("halrun did not load stream.hal")
            time.sleep(0.2)
        sampler = subprocess.Popen(_as_user(name, env, ["halsampler", "-c", "0", "-t", "-n",
                                                        str(n_lines),
                                                        str(work / "record.txt")]),
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        streamer = subprocess.Popen(_as_user(name, env, ["halstreamer", "-c", "0",
                                                         str(work / "stream.txt")]),
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        # the FIFO holds depth - 1 samples
        depth_needed = min(n_lines, _streamer_depth(config) - 1)
        end = time.monotonic() + 60
        while _pin(hal, "streamer.0.curr-depth") < depth_needed:
            if time.monotonic() > end or streamer.poll() not in (None, 0):
                raise LinuxcncFailed("halstreamer did not fill the streamer's FIFO")
            time.sleep(0.05)
        hal("sets", "stream-enable", "1")
        sampler.wait(timeout=timeout + n_lines * _servo_period(config))
        streamer.wait(timeout=30)
        if sampler.returncode != 0 or streamer.returncode != 0:
            raise LinuxcncFailed(f"halsampler exit {sampler.returncode}, halstreamer exit "
                                 f"{streamer.returncode}")
        return read_record(work / "record.txt", STREAM_COLUMNS, _servo_period(config))
    finally:
        for process in (streamer, sampler):
            if process is not None and process.poll() is None:
                process.terminate()
                process.wait(timeout=10)
        if session is not None:
            try:
                log, _ = session.communicate("exit\n", timeout=60)
            except subprocess.TimeoutExpired:
                session.kill()
        shutil.rmtree(work, ignore_errors=True)


def _pin(hal, name: str) -> int:
    out = hal("getp", name, check=False).strip()
    try:
        return int(float(out))
    except ValueError:
        return -1


def _streamer_depth(config: Path) -> int:
    for line in (config / "stream.hal").read_text().splitlines():
        if line.startswith("loadrt streamer"):
            for word in line.split():
                if word.startswith("depth="):
                    return int(word.split("=", 1)[1])
    raise ValueError(f"{config / 'stream.hal'}: no streamer depth")


#: Weights of the joint coordinates for the block-end test of :func:`block_timing`: mm, and
#: 100 mm per rad for rotary joints in degrees (1e-5 rad weighs as 1 um, the default G-code
#: tolerances).
_END_WEIGHTS = np.array([1.0, 1.0, 1.0, 100.0 * np.pi / 180.0, 100.0 * np.pi / 180.0])


@dataclass(frozen=True)
class BlockTiming:
    """Programmed against executed block end times of a ``run`` G-code program on LinuxCNC.

    Times are from the start of the first ``G1`` block (the servo period in which the
    planner starts executing it). A block ends, as executed, when the planner's position
    (``axis.L.pos-cmd``, before motion's cubic interpolator) passes its end point: crosses the
    plane through the end point normal to the chord from the block's start to the next
    block's end (sub-sample, by linear interpolation); dwells (``G4``) have no such point.

    Attributes
    ----------
    line : ndarray of int, shape (K,)
        Program line of each ``G1``/``G4`` block.
    programmed : ndarray, shape (K,)
        Programmed end time of each block, s (sum of 60/F and G4 P).
    executed : ndarray, shape (K,)
        Executed end time, s; NaN for dwells and blocks whose end was not passed.
    rotary : ndarray of bool, shape (K,)
        The block moves a rotary axis (its A/B or C word differs from the previous one).
    ts : float
        Servo period, s.
    """

    line: np.ndarray
    programmed: np.ndarray
    executed: np.ndarray
    rotary: np.ndarray
    ts: float

    @property
    def late(self) -> np.ndarray:
        """executed - programmed, s (NaN where not measured)."""
        return self.executed - self.programmed

    @property
    def measured(self) -> np.ndarray:
        return np.isfinite(self.executed)

    @property
    def duration(self) -> tuple[float, float]:
        """(programmed, executed) time to the end of the last block with a measured end, s."""
        last = np.flatnonzero(self.measured)[-1]
        return float(self.programmed[last]), float(self.executed[last])

    def late_blocks(self, tolerance: float | None = None) -> int:
        """Blocks whose end is more than ``tolerance`` (default one servo period) off."""
        tolerance = self.ts if tolerance is None else tolerance
        return int(np.sum(np.abs(self.late[self.measured]) > tolerance))


def parse_run_gcode(text: str, axis_names: str = "XYZAC"):
    """The start point and the ``G93`` blocks of a program ``run`` (or ``export``) wrote:
    (start (5,), [(line, end (5,), seconds, kind)]), positions in mm and degrees."""
    import re

    word = re.compile(r"([A-Z])\s*([-+]?[0-9]*\.?[0-9]+)")
    start = None
    blocks = []
    inverse_time = False
    position = None
    for number, raw in enumerate(text.splitlines(), 1):
        code = re.sub(r"\([^)]*\)", "", raw).split(";")[0].upper()
        words = word.findall(code)
        gcodes = {float(v) for k, v in words if k == "G"}
        values = {k: float(v) for k, v in words if k != "G"}
        if 93 in gcodes:
            inverse_time = True
        if 94 in gcodes:
            inverse_time = False
        if 0 in gcodes and start is None:
            start = np.array([values[a] for a in axis_names])
            position = start.copy()
        elif inverse_time and 1 in gcodes:
            end = position.copy()
            for i, a in enumerate(axis_names):
                end[i] = values.get(a, end[i])
            blocks.append((number, end, 60.0 / values["F"], "G1"))
            position = end
        elif inverse_time and 4 in gcodes:
            blocks.append((number, position.copy(), values["P"], "G4"))
    if start is None:
        raise ValueError("no G0 to the start point: not a program run or export wrote")
    return start, blocks


#: How far past the previous block's end :func:`block_timing` looks for a block's end, s.
SEARCH_SECONDS = 120.0
#: Distance (mm; rotary joints weighted as :data:`_END_WEIGHTS`) from a block's end point
#: within which a crossing of its plane counts, besides half the block's length.
END_GATE = 0.05


def _crossing(world, lo, hi, end, normal, gate, chunk=4096):
    """Fractional sample in [lo, hi) where ``world`` first crosses the plane through ``end``
    normal to ``normal`` (forwards) within ``gate`` of ``end``; None if it does not."""
    eps = 1e-9 * np.linalg.norm(normal)  # a position exactly on the end point reaches it
    start = lo
    while start < hi - 1:
        stop = min(hi, start + chunk + 1)
        s = (world[start:stop] - end) @ normal + eps
        for j in np.flatnonzero((s[:-1] < 0.0) & (s[1:] >= 0.0)):
            frac = s[j] / (s[j] - s[j + 1])
            point = world[start + j] + frac * (world[start + j + 1] - world[start + j])
            if np.linalg.norm(point - end) <= gate:
                return start + j + frac
        start = stop - 1
    return None


def block_timing(program_text: str, recording: Recording, *,
                 axis_names: str = "XYZAC") -> BlockTiming:
    """Measure each block's executed end time against its programmed one (see
    :class:`BlockTiming`), from a :func:`run_gcode` recording of ``program_text``."""
    start, blocks = parse_run_gcode(program_text, axis_names)
    lines = np.array([b[0] for b in blocks])
    ends = np.array([b[1] for b in blocks])
    kinds = [b[3] for b in blocks]
    programmed = np.cumsum([b[2] for b in blocks])
    points = np.vstack([start, ends])
    rotary = np.any(np.diff(points[:, 3:], axis=0) != 0, axis=1)
    world = np.column_stack([recording.columns[f"w{i}"] for i in range(5)]) * _END_WEIGHTS
    executed_line = recording.columns["line"]
    begun = np.flatnonzero(executed_line == lines[0])
    if begun.size == 0:
        raise ValueError("the recording never executes the program's first block")
    t0 = begun[0]
    weighted = points * _END_WEIGHTS
    executed = np.full(len(blocks), np.nan)
    reach = int(SEARCH_SECONDS / recording.ts)
    i = t0
    for k in range(len(blocks)):
        if kinds[k] != "G1":
            continue
        end = weighted[k + 1]
        normal = weighted[min(k + 2, len(weighted) - 1)] - weighted[k]
        if not np.any(normal):
            continue
        # the plane is crossed elsewhere too where the path comes back: only a crossing near
        # the end point counts (blends cut corners by far less than half a block)
        gate = END_GATE + 0.5 * np.linalg.norm(end - weighted[k])
        found = _crossing(world, i, min(world.shape[0], i + reach), end, normal, gate)
        if found is None:
            continue
        executed[k] = (found - t0) * recording.ts
        i = int(found)
    return BlockTiming(line=lines, programmed=programmed, executed=executed, rotary=rotary,
                       ts=recording.ts)
