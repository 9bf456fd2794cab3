"""Servo traces as commercial controllers export them, and any CSV through a column map.

The readers behind :func:`~precontour.identification.servo_log.read_servo_log`'s formats
``sco``, ``twincat-csv``, ``sinumerik-xml`` and ``csv``. Each returns the log's columns by name
(``t`` in s, ``X..C`` commanded, ``X_act..C_act`` measured, ``line``) and the file's line of
each sample (for messages); the traces record their time stamps, a ``csv`` without a ``t``
column takes the caller's period. The layouts, and the public files they were taken from, are
listed in ``tests/identification/data/SOURCES.md``:

* ``sco``: a Heidenhain TNCscope data file. Lines starting with ``%`` make the header: a
  ``%[GLOBAL]`` section, then one ``%[CURVEn]`` section per channel of ``%KEY=VALUE`` lines
  (``NAME=s ist/X``, ``CHANNELTYPE=s ist``, ``AXISTYPE=X``, ``DIMENSION=mm``, ``COUNT``,
  ``COLUMN``), then ``%[DATA]`` and one row per sample: the time in µs and each channel's value,
  each followed by ``;``. ``s soll`` / ``s ist`` are the commanded and the actual position;
  values in µm are turned into mm, units other than mm, µm and degrees are refused. Heidenhain
  publishes no description of the format: the layout is that of a public file from an
  iTNC 530, whose channels were German (``s ist``, ``v soll``, ``I ist``). Assumed: the English
  types ``s nom`` / ``s actl`` (the "Noml." / "Actl." of Heidenhain's manuals), the rotary
  axes' unit (degrees, ``°`` in the Windows code page), a time column that starts the row.
* ``twincat-csv``: Beckhoff TwinCAT Scope View's CSV export. ``Name`` and the scope's name on
  the first line, whose fifth character is the separator (tab, ``;`` or ``,``); then, after the
  export's time lines, the channel header: a ``Name`` cell starts each time column, the channel
  names after it share that time column (one per channel, or one for all with "exclude double
  time stamps"); metadata rows (``SymbolName``, ``SampleTime[ms]``, ...) down to an empty line;
  then the rows, time in ms, a decimal comma where the separator is not ``,``, an ``EOF`` line
  perhaps. A channel is recognised by its name, else by its symbol (``MAIN.AxisX.NcToPlc.SetPos``,
  the setpoint and actual positions of Beckhoff's NC axis interface ``NCTOPLC_AXIS_REF``).
  Values are read as exported (scaled, if the export scaled them); their unit is not checked,
  as the Scope's ``Unit`` is a display label.
* ``sinumerik-xml``: a Siemens Sinumerik Operate trace saved as XML: the root ``traceSession``;
  ``dataSignal`` elements (``id``, ``key``, ``name`` such as ``/Nck/!SD/nckServoDataActPos2ndEnc64
  [u1, 3]``); ``signal`` elements of the display setup that give a ``key`` its ``description``;
  ``rec`` elements, one per sample time, ``time`` in s and one attribute per signal named by its
  ``id``. A signal's name gives the machine axis by number, not by letter: it is recognised by
  its description (``Lagesollwert X1``, ``Position setpoint X1``) when that names the axis, or
  named with ``columns``. Assumed where no public file showed it: the description holds the
  axis's name, times are in seconds, numbers use a decimal point.
* ``csv``: any delimited text (``;``, tab, ``,`` or blanks, a decimal comma beside ``;`` or
  tabs, ``#`` comment lines), its columns named by ``columns``: a list in file order (``t``,
  ``n``, ``X``, ``X_act``, ``line``, ``I_X``, empty to skip; a header line, if any, is skipped),
  or a map {header: name} (:func:`parse_column_map` reads one from ``"Pos X=X,Act X=X_act"``).

Channels become columns by their names (:func:`recognise`: one of the machine's axis letters and
a setpoint or an actual word, in English or German, and no word of another quantity such as a
velocity, a current or a following error; ``line`` for the program line) or by ``columns``: a
list in channel order, or a map {channel name: column}, which then names every channel used.
Two channels that read as the same column are an error, not a guess.
"""

from __future__ import annotations

import re
from array import array
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from itertools import chain
from pathlib import Path
from types import MappingProxyType
from xml.parsers import expat

import numpy as np

from ..errors import InputError
from ..files import check_input_file, refuse_non_text
from ._log_reading import (Letters, Rows, check_log_name, check_sample_numbers, check_unique,
                           log_names, text_lines)

#: Channel names that are the commanded position ("setpoint" words), lower case.
COMMAND_WORDS = frozenset({
    "set", "setpos", "setpoint", "setposition", "cmd", "command", "commanded", "nom", "noml",
    "nominal", "demand", "soll", "sollwert", "sollpos", "sollposition",
    "lagesollwert", "positionssollwert"})
#: Channel names that are the actual (measured) position, lower case.
ACTUAL_WORDS = frozenset({
    "act", "actl", "actual", "feedback", "meas", "measured", "ist", "istwert", "istpos",
    "istposition", "lageistwert", "positionsistwert"})
#: Words of quantities that are no position, or not the one to identify from (a modulo or an
#: uncorrected position beside TwinCAT's SetPos / ActPos): a channel holding one is no axis.
OTHER_WORDS = frozenset({
    "v", "vel", "velo", "velocity", "speed", "feed", "feedrate", "rpm", "geschw",
    "geschwindigkeit", "drehzahl", "vorschub", "i", "curr", "current", "strom", "torque",
    "force", "moment", "momenten", "kraft", "acc", "accel", "acceleration", "beschleunigung",
    "jerk", "ruck", "lag", "diff", "dif", "dev", "deviation", "err", "error", "fehler",
    "schleppabstand", "schleppfehler", "regeldifferenz", "konturabweichung", "load",
    "auslastung", "power", "leistung", "temp", "temperature", "voltage", "spannung", "offset",
    "comp", "compensation", "correction", "korrektur", "modulo", "target"})
#: Words that say a TNCscope channel type is a position (besides its symbol ``s``).
POSITION_WORDS = frozenset({"s", "pos", "position", "lage", "lagesollwert", "lageistwert",
                            "sollposition", "istposition"})
#: Position units a trace may give, and their factor to mm (linear) or degrees (rotary).
UNIT_SCALE = MappingProxyType({"": 1.0, "mm": 1.0, "µm": 1e-3, "μm": 1e-3, "um": 1e-3,
                               "deg": 1.0, "°": 1.0, "grd": 1.0, "degree": 1.0,
                               "degrees": 1.0})
#: Encoding of a line that is not UTF-8: the Windows tools write the system's code page.
WINDOWS_ENCODING = "cp1252"
#: Channels named in a message before it says how many more there are.
NAMES_SHOWN = 8

_WORD = re.compile(r"[A-ZÄÖÜ]+(?![a-zäöüß])|[A-ZÄÖÜ]?[a-zäöüß]+|\d+[a-z]*")
_MAP_ITEM = re.compile(r'\s*(?:"([^"]*)"|([^="]*?))\s*=\s*([^,="]*?)\s*(?:,|$)')

Columns = Sequence[str] | Mapping[str, str] | None
Read = tuple[dict, list[int]]


@dataclass(frozen=True)
class Channel:
    """One recorded signal: the name a map gives it by, other names it goes by (a symbol, a
    description, an XML id), where its values are (a column, an XML attribute), and, for a
    TNCscope curve, its type, axis, unit and sample count, which that file keeps apart."""

    name: str
    place: int | str
    aliases: tuple[str, ...] = ()
    quantity: str = ""
    axis: str = ""
    unit: str | None = None
    count: int | None = None


# -- names ------------------------------------------------------------------------------------

def parse_column_map(text: str) -> dict[str, str]:
    """A column map ``"Header A=X,Header B=X_act"`` as {header: column name}.

    Pairs are separated by commas; a header may hold commas and blanks (``/Nck/!SD/x [u1, 1]=X``)
    but no ``=``, unless it is in double quotes. The names are checked against the log by
    :func:`~precontour.identification.servo_log.read_servo_log` (an empty one skips a channel).
    """
    text = text.strip()
    if not text:
        raise InputError("column map is empty: give header=name pairs, e.g. 'Pos X=X,Act X=X_act'")
    out: dict[str, str] = {}
    pos = 0
    while pos < len(text):
        match = _MAP_ITEM.match(text, pos)
        if match is None or match.end() == pos:
            raise InputError(f"column map {text!r}: expected header=name at {text[pos:]!r}")
        header = match.group(1) if match.group(1) is not None else match.group(2)
        if not header:
            raise InputError(f"column map {text!r}: a pair without a header before "
                             f"'={match.group(3)}'")
        if header in out:
            raise InputError(f"column map {text!r}: header {header!r} mapped twice")
        out[header] = match.group(3)
        pos = match.end()
    return out


def words(label: str) -> list[str]:
    """The words of a channel name, lower case: split at blanks, punctuation, digits and
    camel case (``NcToPlc.SetPos`` -> nc, to, plc, set, pos)."""
    return [w.lower() for w in _WORD.findall(label)]


def recognise(label: str, letters: Letters) -> str | None:
    """The log column a channel name stands for (``X``, ``X_act``, ``line``), or None.

    An axis position needs exactly one of the machine's axis letters as a word of its own
    (``X``, ``X1``, ``AxisX``), setpoint words or actual words but not both, and no word of
    another quantity: ``Lagesollwert X1`` is X, ``MAIN.AxisX.NcToPlc.ActPos`` is X_act,
    ``SetVelo X`` and ``s diff/X`` are nothing.
    """
    if label.strip().lower() == "line":
        return "line"
    if label.strip() in letters.columns():
        return label.strip()           # the log's own name: X, X_act, I_X
    found = words(label)
    if any(w in OTHER_WORDS for w in found):
        return None
    return _position(found, {w.upper() for w in found} & set(letters.names))


def _position(found: list[str], axes: set[str]) -> str | None:
    command = any(w in COMMAND_WORDS for w in found)
    actual = any(w in ACTUAL_WORDS for w in found)
    if command == actual or len(axes) != 1:
        return None
    letter = axes.pop()
    return letter if command else f"{letter}_act"


def _recognise_channel(channel: Channel, letters: Letters) -> str | None:
    """A channel by its name, else by its other names (a symbol, a description)."""
    for label in (channel.name,) + channel.aliases:
        name = recognise(label, letters)
        if name is not None:
            return name
    return None


def _recognise_curve(channel: Channel, letters: Letters) -> str | None:
    """A TNCscope curve by its type and axis, kept apart in the file (so that ``a soll`` of
    axis A, an acceleration, is no position): the type's first word is ``s`` or a position word."""
    if not (channel.quantity and channel.axis):
        return recognise(channel.name, letters)
    found = words(channel.quantity)
    if (not found or found[0] not in POSITION_WORDS or any(w in OTHER_WORDS for w in found)
            or channel.axis not in letters.names):
        return None
    return _position(found, {channel.axis})


def _assign(channels: Sequence[Channel], columns: Columns, source: str, letters: Letters,
            recognise_channel: Callable[[Channel, Letters], str | None]) -> list[str]:
    """The log column of each channel ('' for one not used): by ``columns`` (a list in channel
    order, or a map {channel name: column}), else by the channels' names."""
    if isinstance(columns, Mapping):
        return _mapped(channels, columns, source, letters)
    if columns is not None:
        return log_names(columns, len(channels), source, letters)
    names = [recognise_channel(channel, letters) or "" for channel in channels]
    for name in set(names) - {""}:
        twice = [c.name for c, n in zip(channels, names) if n == name]
        if len(twice) > 1:
            raise InputError(f"channels {twice[0]!r} and {twice[1]!r} both read as {name}: name "
                             f"the one to use with a column map (--column-map "
                             f"'{twice[0]}={name},...')", source=source)
    if not any(name and name != "line" for name in names):
        raise InputError(f"no channel is recognised as an axis position: {_listed(channels)}; "
                         "name them with a column map (--column-map 'Pos X=X,Act X=X_act')",
                         source=source)
    return names


def map_labels(labels: Sequence[str], columns: Mapping[str, str], source: str,
               letters: Letters) -> list[str]:
    """The column a map {label: column} gives each of ``labels`` ('' for one it leaves out)."""
    return _mapped([Channel(name=label, place=i) for i, label in enumerate(labels)], columns,
                   source, letters)


def _mapped(channels: Sequence[Channel], columns: Mapping[str, str], source: str,
            letters: Letters) -> list[str]:
    index = {}
    for i, channel in enumerate(channels):
        for label in (channel.name,) + channel.aliases:
            index.setdefault(label.strip(), i)
    names = [""] * len(channels)
    named = set()
    for label, name in columns.items():
        i = index.get(label.strip())
        if i is None:
            raise InputError(f"no channel {label!r} in the file; it has {_listed(channels)}",
                             source=source, field=label)
        if i in named:
            raise InputError(f"the column map names channel {channels[i].name!r} twice",
                             source=source, field=label)
        named.add(i)
        names[i] = check_log_name(name, source, letters)
    check_unique(names, source)
    return names


def _listed(channels: Sequence[Channel]) -> str:
    shown = ", ".join(repr(c.name) for c in channels[:NAMES_SHOWN])
    more = len(channels) - NAMES_SHOWN
    return shown + (f" and {more} more" if more > 0 else "") if channels else "no channels"


def _used(channels: Sequence[Channel], names: Sequence[str], source: str
          ) -> list[tuple[Channel, str]]:
    """The channels read, with their columns: at least one; a trace's own time stamps are
    its time, so no channel of it may be named t or n."""
    used = [(channel, name) for channel, name in zip(channels, names) if name]
    if not used:
        raise InputError("no channel of the trace is read: the columns name none",
                         source=source)
    clash = [name for _, name in used if name in ("t", "n")]
    if clash:
        raise InputError(f"column {clash[0]!r} names no channel of a trace: it has its own time",
                         source=source, field=clash[0])
    return used


def _unit_scale(channel: Channel, name: str, source: str) -> float:
    """The factor that brings a position channel to mm or degrees (a line number has none)."""
    if name in ("line", "t", "n") or name.startswith("I_") or channel.unit is None:
        return 1.0
    scale = UNIT_SCALE.get(channel.unit.strip())
    if scale is None:
        raise InputError(f"unit {channel.unit!r} of channel {channel.name!r}: positions are read "
                         "in mm, µm or degrees", source=source, field=channel.name)
    return scale


# -- Heidenhain TNCscope (.sco) ---------------------------------------------------------------

def read_sco(path: Path, columns: Columns, letters: Letters) -> Read:
    """A TNCscope data file (see the module docstring)."""
    source = str(path)
    lines = text_lines(path, WINDOWS_ENCODING)
    channels = _sco_curves(lines, source)
    names = _assign(channels, columns, source, letters, _recognise_curve)
    used = _used(channels, names, source)
    scales = [_unit_scale(channel, name, source) for channel, name in used]
    places = [0] + [channel.place for channel, _ in used]
    fields = ["time"] + [channel.name for channel, _ in used]
    counts = {channel.count for channel, _ in used} - {None}
    if len(counts) > 1:
        raise InputError(f"the curves used hold different numbers of samples (COUNT "
                         f"{', '.join(str(c) for c in sorted(counts))})", source=source)
    count = counts.pop() if counts else None
    rows = Rows(len(places))
    width = None
    for number, text in lines:
        if len(rows) == count:
            break
        text = text.strip()
        if not text:
            continue
        cells = text.split(";")
        if not cells[-1].strip():
            cells.pop()       # each value is followed by ';'
        if width is None:
            width = len(cells)
            if width <= max(places):
                raise InputError(f"{width} values on the first row, but curve columns up to "
                                 f"{max(places)} after the time", source=source, row=number)
        elif len(cells) != width:
            raise InputError(f"expected {width} values, found {len(cells)}", source=source,
                             row=number)
        rows.add(number, [cells[p] for p in places], fields, source)
    if count is not None and len(rows) < count:
        raise InputError(f"the data ends after {len(rows)} rows, the curves hold {count} (COUNT): "
                         "a truncated file?", source=source)
    table = rows.table()
    data = {"t": table[:, 0] * 1e-6}   # TNCscope's time column counts µs
    for k, ((_, name), scale) in enumerate(zip(used, scales), start=1):
        data[name] = table[:, k] * scale
    return data, rows.lines.tolist()


def _sco_curves(lines: Iterator[tuple[int, str]], source: str) -> list[Channel]:
    """The channels of a TNCscope header, read up to and including its ``%[DATA]`` line."""
    first = next(lines, None)
    if first is None:
        raise InputError("empty file", source=source)
    if not first[1].lstrip().startswith("%"):
        raise InputError("not a TNCscope data file: its first line must start with '%' "
                         "('%TNCscopeNT data file')", source=source, row=1)
    curves: list[tuple[int, dict]] = []
    section = ""
    for number, text in lines:
        text = text.strip()
        if not text:
            continue
        if not text.startswith("%"):
            raise InputError("a row of values before the '%[DATA]' line: not a TNCscope data "
                             "file", source=source, row=number)
        body = text[1:].strip()
        if body.upper() == "[DATA]":
            if not curves:
                raise InputError("no '%[CURVEn]' section before the data", source=source,
                                 row=number)
            return [_sco_channel(i, row, keys, source) for i, (row, keys) in enumerate(curves)]
        if body.startswith("[") and body.endswith("]"):
            section = body[1:-1].strip().upper()
            if section.startswith("CURVE"):
                curves.append((number, {"section": section}))
        elif "=" in body and section.startswith("CURVE"):
            key, _, value = body.partition("=")
            curves[-1][1][key.strip().upper()] = value.strip()
    raise InputError("no '%[DATA]' line: not a TNCscope data file", source=source)


def _sco_channel(index: int, row: int, keys: dict, source: str) -> Channel:
    def whole(key: str, default: int | None) -> int | None:
        if key not in keys:
            return default
        try:
            value = int(keys[key])
        except ValueError:
            value = -1
        if value < (1 if key == "COLUMN" else 0):
            raise InputError(f"{key}={keys[key]!r} is no valid count", source=source, row=row,
                             field=key)
        return value

    quantity, axis = keys.get("CHANNELTYPE", ""), keys.get("AXISTYPE", "")
    name = keys.get("NAME") or (f"{quantity}/{axis}" if quantity else keys["section"])
    return Channel(name=name, place=whole("COLUMN", index + 1), aliases=(keys["section"],),
                   quantity=quantity, axis=axis, unit=keys.get("DIMENSION"),
                   count=whole("COUNT", None))


# -- Beckhoff TwinCAT Scope View (CSV export) --------------------------------------------------

def read_twincat(path: Path, columns: Columns, letters: Letters) -> Read:
    """A TwinCAT Scope View CSV export (see the module docstring)."""
    source = str(path)
    lines = text_lines(path, WINDOWS_ENCODING)
    separator = _twincat_separator(next(lines, None), source)
    channels, times, pending = _twincat_header(lines, separator, source)
    names = _assign(channels, columns, source, letters, _recognise_channel)
    used = _used(channels, names, source)
    time_places = list(dict.fromkeys(times[channel.name] for channel, _ in used))
    places = time_places + [channel.place for channel, _ in used]
    fields = _time_fields(used, times, time_places) + [channel.name for channel, _ in used]
    rows = _twincat_rows(chain(pending, lines), separator, places, fields, source)
    table = rows.table()
    line_numbers = rows.lines.tolist()
    stamps = {place: table[:, k] for k, place in enumerate(time_places)}
    first = used[0][0]
    t = stamps[times[first.name]]
    for channel, _ in used[1:]:
        k = _first_difference(t, stamps[times[channel.name]])
        if k is not None:
            raise InputError(f"channels {first.name!r} and {channel.name!r} have different time "
                             "stamps: record the axes at one sample time", source=source,
                             row=line_numbers[k], field=channel.name)
    data = {"t": t * 1e-3}     # the export's times are in ms
    for k, (channel, name) in enumerate(used, start=len(time_places)):
        data[name] = table[:, k]
    return data, line_numbers


def _time_fields(used, times: dict, time_places: list[int]) -> list[str]:
    """Message names of the time columns: 'time of' the first channel using each."""
    out = []
    for place in time_places:
        owner = next(channel.name for channel, _ in used if times[channel.name] == place)
        out.append(f"time of {owner}")
    return out


def _twincat_separator(first, source: str) -> str:
    if first is None:
        raise InputError("empty file", source=source)
    text = first[1]
    if not text.startswith("Name") or len(text) < 5:
        raise InputError("not a TwinCAT Scope export: its first line must be 'Name' and the "
                         "scope's name", source=source, row=1)
    separator = text[4]
    if separator not in ("\t", ";", ","):
        raise InputError(f"separator {separator!r}: export with tab, ';' or ',' separators (a "
                         "channel name may hold blanks and colons)", source=source, row=1)
    return separator


def _twincat_header(lines, separator: str, source: str
                    ) -> tuple[list[Channel], dict[str, int], list[tuple[int, str]]]:
    """The channels (with their symbols), the time column of each, and the first row of
    values if no empty line ended the metadata rows before it."""
    for number, text in lines:
        cells = [c.strip() for c in text.rstrip("\r\n").split(separator)]
        if cells[0] == "Name" and len(cells) > 1:
            break
        if _is_number(cells[0]):
            raise InputError("values before the channel header (a row starting with 'Name'): "
                             "not a TwinCAT Scope export", source=source, row=number)
    else:
        raise InputError("no channel header (a row starting with 'Name'): not a TwinCAT Scope "
                         "export", source=source)
    places, times, time_place = {}, {}, 0
    for place, cell in enumerate(cells):
        if cell == "Name":
            time_place = place
        elif cell:
            if cell in places:
                raise InputError(f"two channels named {cell!r}", source=source, row=number)
            places[cell], times[cell] = place, time_place
    if not places:
        raise InputError("the channel header names no channel", source=source, row=number)
    symbols: dict[str, str] = {}
    pending: list[tuple[int, str]] = []
    for number, text in lines:
        cells = [c.strip() for c in text.rstrip("\r\n").split(separator)]
        if not any(cells):
            break
        if _is_number(cells[0]):
            pending.append((number, text))
            break
        for name, place in places.items():
            if cells[times[name]:times[name] + 1] == ["SymbolName"] and place < len(cells):
                symbols[name] = cells[place]
    channels = [Channel(name=name, place=place,
                        aliases=(symbols[name],) if symbols.get(name) else ())
                for name, place in places.items()]
    return channels, times, pending


def _twincat_rows(lines, separator: str, places: list[int], fields: list[str],
                  source: str) -> Rows:
    """The values at ``places`` of every row, down to the end of the channels used (later
    rows of other, longer channels leave them empty) or an ``EOF`` line."""
    rows = Rows(len(places))
    comma = separator != ","
    ended = None
    for number, text in lines:
        if not text.strip():
            continue
        cells = text.rstrip("\r\n").split(separator)
        if cells[0].strip() == "EOF":
            break
        picked = [cells[p].strip() if p < len(cells) else "" for p in places]
        if not any(picked):
            ended = ended or number
            continue
        if ended is not None:
            raise InputError(f"values again after the channels used ended on row {ended}: a "
                             "gap", source=source, row=number)
        if not all(picked):
            k = picked.index("")
            raise InputError("no value here, where the other channels used have one (another "
                             "sample time?)", source=source, row=number, field=fields[k])
        if comma:
            picked = [p.replace(",", ".") for p in picked]
        rows.add(number, picked, fields, source)
    if not len(rows):
        raise InputError("no samples", source=source)
    return rows


def _first_difference(a: np.ndarray, b: np.ndarray) -> int | None:
    """The first index where ``a`` and ``b`` differ, or where the shorter ends; None if equal."""
    n = min(a.size, b.size)
    differ = np.flatnonzero(a[:n] != b[:n])
    if differ.size:
        return int(differ[0])
    return None if a.size == b.size else n


def _is_number(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


# -- Siemens Sinumerik Operate trace (XML) -----------------------------------------------------

def read_sinumerik(path: Path, columns: Columns, letters: Letters) -> Read:
    """A Sinumerik Operate trace saved as XML (see the module docstring)."""
    source = str(path)
    trace = _SinumerikTrace(source)
    trace.parse(path)
    channels = trace.channels()
    names = _assign(channels, columns, source, letters, _recognise_channel)
    used = _used(channels, names, source)
    signals = [trace.signals[channel.place] for channel, _ in used]
    for signal in signals:
        if signal.bad is not None:
            raise InputError(f"not a number: {signal.bad[1]!r}", source=source,
                             row=signal.bad[0], field=signal.name)
        if not len(signal.times):
            raise InputError("no samples of this signal", source=source, field=signal.name)
    first = signals[0]
    t = np.frombuffer(first.times, dtype=float)
    for signal in signals[1:]:
        k = _first_difference(t, np.frombuffer(signal.times, dtype=float))
        if k is not None:
            line = (signal if k < len(signal.lines) else first).lines[k]
            raise InputError(f"signals {first.name!r} and {signal.name!r} are not sampled at the "
                             "same times: record the axes at one sample time", source=source,
                             row=line, field=signal.name)
    data = {"t": t.copy()}
    for (channel, name), signal in zip(used, signals):
        data[name] = np.frombuffer(signal.values, dtype=float).copy()
    return data, first.lines.tolist()


class _Signal:
    """The samples of one ``dataSignal``: time, value and XML line of each ``rec`` holding it,
    and the first value that is no number (raised only if the signal is used)."""

    def __init__(self, name: str):
        self.name = name
        self.times = array("d")
        self.values = array("d")
        self.lines = array("q")
        self.bad: tuple[int, str] | None = None

    def add(self, time: float, text: str, line: int) -> None:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
            if self.bad is None:
                self.bad = (line, text)
        self.times.append(time)
        self.values.append(value)
        self.lines.append(line)


class _SinumerikTrace:
    """The signals and samples of a trace file, parsed as a stream (expat), so that a large
    trace is never held as a tree and every element's line is known for messages."""

    CHUNK = 1 << 16

    def __init__(self, source: str):
        self.source = source
        self.signals: dict[str, _Signal] = {}
        self.keys: dict[str, str] = {}           # id -> key
        self.descriptions: dict[str, str] = {}   # key -> description
        self.root: str | None = None
        self.parser = None

    def parse(self, path: Path) -> None:
        check_input_file(path)
        parser = self.parser = expat.ParserCreate()
        parser.StartElementHandler = self._start
        parser.StartDoctypeDeclHandler = self._refuse_dtd
        parser.EntityDeclHandler = self._refuse_dtd
        try:
            handle = open(path, "rb")
        except OSError as exc:
            raise InputError(f"cannot read file: {exc.strerror or exc}",
                             source=self.source) from None
        with handle:
            first = True
            while True:
                chunk = handle.read(self.CHUNK)
                if first:
                    refuse_non_text(chunk, self.source)
                    first = False
                self._feed(chunk, final=not chunk)
                if not chunk:
                    break
        if not self.signals:
            raise InputError("no dataSignal element: a trace without signals", source=self.source)

    def _feed(self, chunk: bytes, final: bool) -> None:
        try:
            self.parser.Parse(chunk, final)
        except expat.ExpatError as exc:
            raise InputError(f"not a well-formed XML file: {expat.ErrorString(exc.code)}",
                             source=self.source, row=exc.lineno) from None

    def _refuse_dtd(self, *args) -> None:
        raise InputError("a document type or entity declaration: not a Sinumerik trace",
                         source=self.source, row=self.parser.CurrentLineNumber)

    def _start(self, tag: str, attrs: dict) -> None:
        line = self.parser.CurrentLineNumber
        if self.root is None:
            self.root = tag
            if tag != "traceSession":
                raise InputError(f"not a Sinumerik trace: the root element is <{tag}>, not "
                                 "<traceSession>", source=self.source, row=line)
        if tag == "rec":
            self._rec(attrs, line)
        elif tag == "dataSignal":
            self._data_signal(attrs, line)
        elif tag == "signal" and attrs.get("key") and attrs.get("description"):
            self.descriptions[attrs["key"]] = attrs["description"]

    def _data_signal(self, attrs: dict, line: int) -> None:
        ident, name = attrs.get("id"), attrs.get("name")
        if not ident or not name or ident == "time":
            raise InputError("a dataSignal needs an id and a name", source=self.source, row=line)
        if ident in self.signals:
            raise InputError(f"two dataSignals of id {ident!r}", source=self.source, row=line)
        self.signals[ident] = _Signal(name)
        self.keys[ident] = attrs.get("key", "")

    def _rec(self, attrs: dict, line: int) -> None:
        text = attrs.get("time")
        if text is None:
            raise InputError("a rec without its time", source=self.source, row=line,
                             field="time")
        try:
            time = float(text)
        except ValueError:
            raise InputError(f"not a number: {text!r}", source=self.source, row=line,
                             field="time") from None
        for ident, value in attrs.items():
            if ident == "time":
                continue
            signal = self.signals.get(ident)
            if signal is None:
                raise InputError(f"a value of no dataSignal ({ident}={value!r})",
                                 source=self.source, row=line, field=ident)
            signal.add(time, value, line)

    def channels(self) -> list[Channel]:
        out = []
        for ident, signal in self.signals.items():
            description = self.descriptions.get(self.keys[ident])
            aliases = ((description,) if description else ()) + (ident,)
            out.append(Channel(name=signal.name, place=ident, aliases=aliases))
        return out


# -- any CSV, through a column map -------------------------------------------------------------

def read_csv(path: Path, columns: Columns, letters: Letters) -> Read:
    """Any delimited text whose columns ``columns`` names (see the module docstring)."""
    source = str(path)
    if columns is None:
        raise InputError("name the columns: a list in file order (--columns t,X,X_act) or a "
                         "map {header: name} (--column-map 'Pos X=X,Act X=X_act')", source=source)
    lines = ((n, t) for n, t in text_lines(path, WINDOWS_ENCODING)
             if t.strip() and not t.lstrip().startswith("#"))
    head = next(lines, None)
    if head is None:
        raise InputError("no samples", source=source)
    separator = next((s for s in (";", "\t", ",") if s in head[1]), None)
    cells = _split(head[1], separator)
    comma = separator != ","      # a decimal comma, where it cannot be the separator
    header = not all(_is_number(c) if comma else _is_float(c) for c in cells)
    headers = [c.strip().strip('"').strip() for c in cells] if header else None
    if isinstance(columns, Mapping):
        if headers is None:
            raise InputError("a column map needs a header line naming the columns; this file "
                             "starts with values (give the names as a list)", source=source,
                             row=head[0])
        names = map_labels(headers, columns, source, letters)
    else:
        names = log_names(columns, len(cells), source, letters)
    places = [i for i, name in enumerate(names) if name]
    if not places:
        raise InputError("no column of the file is read: the columns name none", source=source)
    used = [names[i] for i in places]
    fields = [headers[i] for i in places] if headers else used    # messages say the file's names
    rows = Rows(len(places))
    for number, text in (lines if header else chain([head], lines)):
        row = _split(text, separator)
        if len(row) != len(cells):
            raise InputError(f"expected {len(cells)} values, found {len(row)}", source=source,
                             row=number)
        picked = [row[p] for p in places]
        rows.add(number, [p.replace(",", ".") for p in picked] if comma else picked, fields,
                 source)
    if not len(rows):
        raise InputError("no samples", source=source)
    table = rows.table()
    line_numbers = rows.lines.tolist()
    data = {name: table[:, k] for k, name in enumerate(used)}
    check_sample_numbers(data, line_numbers, source)
    return data, line_numbers


def _split(text: str, separator: str | None) -> list[str]:
    """The cells of a line: split at ``separator``, or at blanks where there is none; a
    separator ending the line adds no cell."""
    cells = text.rstrip("\r\n").split(separator) if separator else text.split()
    if separator and len(cells) > 1 and not cells[-1].strip():
        cells.pop()
    return cells


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


