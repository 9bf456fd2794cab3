"""One smooth five-axis motion, written in the layout of each controller's servo trace.

The files under ``data/`` are this module's output (``python tests/identification/trace_samples.py``
writes them again); ``data/SOURCES.md`` says which public file or page each layout follows.
The tests read every file back and compare it with a halsampler log of the same motion.
Numbers are printed with 16 significant digits (the controllers print fewer), so that every
file holds the motion to 1e-12 and the comparison can ask for 1e-9.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data"
#: Samples and their period (s): 0.2 s of motion at a 1 kHz servo rate.
N = 200
PERIOD = 1e-3
#: The actual position trails the command by this time (s), as a servo loop's lag does.
LAG = 1.2e-3
AXES = ("X", "Y", "Z", "A", "C")
ROTARY = ("A", "C")


def _path(axis: str, t: np.ndarray) -> np.ndarray:
    """The commanded position of ``axis`` at times ``t``: mm for X Y Z, degrees for A C."""
    w = 2 * np.pi
    return {"X": 40.0 + 6.0 * np.sin(w * 2.5 * t),
            "Y": -15.0 + 4.0 * np.cos(w * 2.0 * t) - 3.0 * t,
            "Z": 80.0 - 20.0 * t + 0.5 * np.sin(w * 4.0 * t),
            "A": 10.0 * np.sin(w * 1.5 * t),
            "C": 120.0 + 30.0 * t + 5.0 * np.sin(w * 3.0 * t)}[axis]


def motion() -> dict[str, np.ndarray]:
    """t (s), X..C commanded, X_act..C_act actual (mm, degrees) and the program line."""
    t = np.arange(N) * PERIOD
    out = {"t": t}
    for axis in AXES:
        out[axis] = _path(axis, t)
        out[f"{axis}_act"] = _path(axis, t - LAG)
    out["line"] = 20.0 + 2.0 * (np.arange(N) // 50)
    return out


def _g(value: float) -> str:
    return f"{value:.16g}"


def halsampler_text(names: list[str]) -> str:
    """The motion as ``halsampler -t`` prints it: the sample number, then ``names``' values."""
    m = motion()
    return "".join(" ".join([str(k)] + [_g(m[name][k]) for name in names]) + "\n"
                   for k in range(N))


# -- Heidenhain TNCscope ----------------------------------------------------------------------

def tnc_number(value: float) -> str:
    """A number as TNCscope prints it (Windows printf: three exponent digits), 16 digits."""
    mantissa, exponent = f"{value:.15e}".split("e")
    return f"{mantissa}e{exponent[0]}{int(exponent[1:]):03d}"


def sco_text() -> str:
    """The motion as a TNCscope data file: per axis the nominal (``s soll``) and actual
    (``s ist``) position, and two channels of other quantities that the reader must pass by."""
    m = motion()
    curves = []
    for axis in AXES:
        unit = "°" if axis in ROTARY else "mm"
        curves += [("s soll", axis, unit, 3, m[axis]), ("s ist", axis, unit, 2, m[f"{axis}_act"])]
    speed = np.gradient(m["X_act"], PERIOD) * 60.0
    curves.insert(2, ("v ist", "X", "mm/min", 6, speed))
    curves.append(("I ist", "X", "Ampere", 43, 0.5 * np.cos(m["t"] * 9.0)))
    head = ["%TNCscopeNT data file", "% ", "%[GLOBAL]", "%VERSION=2.0", "%DIAGTYPE=0",
            "%RECORDEDBY=2", "%CONTROL=iTNC530", "%NCVERSION=606420 03 SP4",
            "%TIME=1648048946", "%TRIGGERTIME=1648048946", "%TRIGGERTIME_US=0",
            "%DIFFTIMEUTC=3600", "%BUFFER=524288", "%SAMPLING=1000", "%TRIGGERMODE=-1", "% "]
    for column, (kind, axis, unit, ident, _) in enumerate(curves, start=1):
        head += [f"%[CURVE{column}]", f"%NAME={kind}/{axis}", f"%CHANNELTYPE={kind}",
                 f"%CHANNELID={ident}", f"%AXISTYPE={axis}", f"%DIMENSION={unit}",
                 f"%COUNT={N}", "%SAMPLING=1000", "%CYCLETIME=1000", "%COLOR=255 0 0",
                 "%TRIGGERCOND=-1", "%LOGIC=0", "%DISCRETE=0", "%METRIC=1", f"%COLUMN={column}",
                 "%BIT=-1", "%NUMSYS=d", "% "]
    head.append("%[DATA]")
    rows = []
    for k in range(N):
        values = [m["t"][k] * 1e6] + [curve[4][k] for curve in curves]
        rows.append("".join(f"{' ' if v >= 0 else ''}{tnc_number(v)}; " for v in values))
    return "\r\n".join(head + rows) + "\r\n"


# -- Beckhoff TwinCAT Scope View --------------------------------------------------------------

def twincat_text(separator: str, shared_time: bool, decimal: str, eof: bool) -> str:
    """The motion as Scope View's CSV export: ``shared_time`` is the export option "exclude
    double time stamps" (one time column for channels of one sample time)."""
    m = motion()
    channels = []   # (name, symbol, values)
    for i, axis in enumerate(AXES, start=1):
        channels.append((f"MAIN.Axis{axis}.NcToPlc.SetPos" if not shared_time else f"SetPos {i}",
                         f"MAIN.Axis{axis}.NcToPlc.SetPos", m[axis]))
        channels.append((f"MAIN.Axis{axis}.NcToPlc.ActPos" if not shared_time else f"ActPos {i}",
                         f"MAIN.Axis{axis}.NcToPlc.ActPos", m[f"{axis}_act"]))
    channels.append(("MAIN.AxisX.NcToPlc.ActVelo", "MAIN.AxisX.NcToPlc.ActVelo",
                     np.gradient(m["X_act"], PERIOD)))
    if shared_time:
        channels.append(("line", "MAIN.nActLine", m["line"]))

    def number(value: float) -> str:
        text = _g(value)
        return text.replace(".", ",") if decimal == "," else text

    def row(key: str, values: list[str]) -> str:
        if shared_time:
            return separator.join([key] + values)
        return separator.join(f"{key}{separator}{v}" for v in values)

    lines = [f"Name{separator}precontour_sample",
             f"File{separator}C:\\TwinCAT\\Scope\\precontour_sample.csv",
             f"Starttime of export{separator}133574400000000000{separator}Montag, 15. April "
             f"2024{separator}08:00:00.000",
             f"Endtime of export{separator}133574400020000000{separator}Montag, 15. April "
             f"2024{separator}08:00:00.200", "", ""]
    lines.append(row("Name", [name for name, _, _ in channels]))
    lines.append(row("SymbolComment", ["" for _ in channels]))
    lines.append(row("Data-Type", ["REAL64" for _ in channels]))
    lines.append(row("SampleTime[ms]", ["1" for _ in channels]))
    lines.append(row("VariableSize", ["8" for _ in channels]))
    lines.append(row("SymbolBased", ["True" for _ in channels]))
    lines.append(row("SymbolName", [symbol for _, symbol, _ in channels]))
    lines.append(row("NetID", ["5.23.41.12.1.1" for _ in channels]))
    lines.append(row("Port", ["851" for _ in channels]))
    lines.append(row("Unit", ["(None)" for _ in channels]))
    lines.append("")
    for k in range(N):
        ms = number(k * PERIOD * 1e3)
        values = [number(values[k]) for _, _, values in channels]
        lines.append(separator.join([ms] + values) if shared_time
                     else separator.join(f"{ms}{separator}{v}" for v in values))
    if eof:
        lines.append("EOF")
    return "\r\n".join(lines) + "\r\n"


# -- Siemens Sinumerik Operate trace -----------------------------------------------------------

#: Machine axis numbers of the sample's axes (the trace names a signal by its axis number).
SINUMERIK_AXIS_NUMBERS = {"X": 1, "Y": 2, "Z": 3, "A": 4, "C": 5}


def sinumerik_text() -> str:
    """The motion as a Sinumerik Operate trace saved as XML: per axis the position setpoint and
    the actual position of the direct measuring system, and the contour deviation of X."""
    m = motion()
    signals = []   # (name, description, values)
    for axis in AXES:
        n = SINUMERIK_AXIS_NUMBERS[axis]
        signals.append((f"/Nck/!SEMA/cmdContrPos [u1, {n}]", f"Lagesollwert {axis}1", m[axis]))
        signals.append((f"/Nck/!SD/nckServoDataActPos2ndEnc64 [u1, {n}]",
                        f"Lageistwert Messsystem 2 {axis}1", m[f"{axis}_act"]))
    signals.append(("/Nck/!SD/nckServoDataContDev64 [u1, 1]", "Konturabweichung X1",
                    m["X"] - m["X_act"]))
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', '<traceSession version="1.0">',
             "  <traceCaptureSetup>",
             '    <sessionSettings sessionName="precontour sample"/>',
             "  </traceCaptureSetup>", "  <traceDisplaySetup>", "    <signals>"]
    for i, (name, description, _) in enumerate(signals, start=1):
        lines.append(f'      <signal key="k{i}" name="{name}" description="{description}"/>')
    lines += ["    </signals>", "  </traceDisplaySetup>", "  <traceData>", "    <dataFrame>",
              '      <frameHeader startTime="2024-04-15T08:00:00.000"/>']
    for i, (name, _, _) in enumerate(signals, start=1):
        lines.append(f'      <dataSignal id="f{i}" key="k{i}" name="{name}"/>')
    for k in range(N):
        values = " ".join(f'f{i}="{_g(v[k])}"' for i, (_, _, v) in enumerate(signals, start=1))
        lines.append(f'      <rec time="{_g(m["t"][k])}" {values}/>')
    lines += ["    </dataFrame>", "  </traceData>", "</traceSession>"]
    return "\r\n".join(lines) + "\r\n"


# -- any CSV -----------------------------------------------------------------------------------

#: The header of the generic CSV sample, and the column each header is.
CSV_HEADERS = {"Zeit [s]": "t", **{f"Pos {a} soll": a for a in AXES},
               **{f"Pos {a} ist": f"{a}_act" for a in AXES}, "Satz": "line"}


def csv_text() -> str:
    """The motion as a spreadsheet's CSV of German locale: ';' separators, decimal commas, a
    header of the file's own names, and one column (a spindle speed) that is not read."""
    m = motion()
    headers = list(CSV_HEADERS)
    lines = [";".join(headers[:1] + ["Drehzahl S1"] + headers[1:])]
    for k in range(N):
        cells = [_g(m[CSV_HEADERS[h]][k]).replace(".", ",") for h in headers]
        lines.append(";".join(cells[:1] + ["12000"] + cells[1:]))
    return "\n".join(lines) + "\n"


#: Each sample file, the function that writes it, and its encoding.
SAMPLES = {
    "tncscope.sco": (sco_text, "cp1252"),
    "twincat_tab.csv": (lambda: twincat_text("\t", False, ",", False), "utf-8"),
    "twincat_semicolon.csv": (lambda: twincat_text(";", True, ".", True), "utf-8"),
    "twincat_comma.csv": (lambda: twincat_text(",", False, ".", False), "utf-8"),
    "sinumerik_trace.xml": (sinumerik_text, "utf-8"),
    "spreadsheet.csv": (csv_text, "utf-8"),
}


def write_samples(folder: Path = DATA) -> list[Path]:
    """Write every sample file into ``folder``; return their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, (text, encoding) in SAMPLES.items():
        path = folder / name
        path.write_bytes(text().encode(encoding))
        paths.append(path)
    return paths


if __name__ == "__main__":
    for written in write_samples():
        print(f"wrote {written}")
