"""Reading a G-code program's lines (the reader's :class:`~.gcode._Reader` mixes this in):
the O-word structure, what kind each line is (worked out once), its code and comments as
written, its words, and the plain motion blocks (``[N..] [G0|G1] axis words [F..]``) executed
together, vectorized. A refusal names what the line holds, as written (the
program's language when it shows another controller's)."""

from __future__ import annotations

import math
import re

import numpy as np
import pyarrow as pa

from ..errors import ProgramError
from ._common import INCH
from ._gcode_codes import (MAX_COORDINATE, _BLANKS, _BLANK_CHARS, _COMMENT, _FANUC_MACRO, _GENERAL,
                           _MAYBE_OWORD, _NAME, _PLAIN, _SETTINGS, _SINUMERIK, _SKIP, _TRAORI,
                           _WORD, _ffill, _unknown_name, _word_at)
from ._ngc import StructureError, needs_macro_reader, scan_structure


class LineReading:
    """The reader's lines: their kinds, codes, comments and words."""

    def scan(self, lines):
        """The O-word structure of the program (subroutines, branches, loops, labels)."""
        codes = [None] * len(lines)
        for index, raw in enumerate(lines):
            if _MAYBE_OWORD.match(raw):
                self.row = index + 1     # the line a comment error names
                codes[index] = self.code_of(raw)[0]
        try:
            return scan_structure(codes)
        except StructureError as exc:
            raise ProgramError(exc.message, source=self.source, row=exc.index + 1,
                               field=exc.word) from None

    def block(self, pc: int, raw: str) -> bool:
        """Execute one line; True after the program end (M2/M30). Plain motion blocks
        (``[N..] [G0|G1] axis words [F..]`` in the machine's axis order) are collected and
        executed together by :meth:`flush`. What a line is, is worked out once (loops and
        subroutines run lines again)."""
        prepared = self.prepared[pc]
        if prepared is None:
            prepared = self.prepared[pc] = self.prepare(raw)
        kind = prepared[0]
        if kind == _PLAIN:
            if self.start is not None:
                self.pending.append((self.row, prepared[1], raw))
                return False
            prepared = self.prepared[pc] = self.prepare(raw, plain=False)
        self.flush()
        return self._run_prepared(prepared)

    def prepare(self, raw: str, plain: bool = True):
        """What kind of line ``raw`` is, and what executing it needs."""
        if plain and "(" not in raw and ";" not in raw:
            code = raw.upper().translate(_BLANKS)
            if code and code[0] not in "%/":
                match = self.plain.fullmatch(code)
                if match is not None:
                    return (_PLAIN, match.groups())
        s = raw.lstrip()
        if s[:1] == "/" and self.block_delete:
            return (_SKIP, True)
        if self.sinumerik:
            parsed = self.sinumerik_prepare(raw)
            if parsed is not None:
                return (_SINUMERIK, *parsed, raw.strip())
        code, comments = self.code_of(raw)
        if not code:
            return (_COMMENT, raw.strip()) if comments else (_SKIP, False)
        traori = trafoof = False
        if "TRA" in code:
            code, n_on = _TRAORI.subn("", code)
            code, n_off = re.subn("TRAFOOF", "", code)
            traori, trafoof = n_on > 0, n_off > 0
        fanuc = _FANUC_MACRO.match(code)
        if fanuc:
            self.fail("Fanuc macro statements (IF GOTO, WHILE DO END) are not supported; "
                      "LinuxCNC's O-word if and while are", fanuc.group())
        if code[:1] == "#" and not comments and needs_macro_reader(code):
            compiled = self.compile(code, raw)
            if not compiled.words:
                return (_SETTINGS, code)
        return (_GENERAL, code, traori, trafoof, raw.strip(), comments)

    def flush(self):
        """Execute the collected plain blocks at once; if any of them needs a word-by-word
        look (an error to report), all are executed one by one instead."""
        pending, self.pending = self.pending, []
        if pending and not self.plain_blocks(pending):
            row = self.row
            for pending_row, _, raw in pending:
                self.row = pending_row
                self.general(raw)
            self.row = row

    def plain_blocks(self, pending) -> bool:
        """Vectorized :meth:`general` for plain blocks: False (nothing changed) if one of them
        needs the general path."""
        if self.dwo_base is not None:
            return False    # G254 turns the work offset block by block (dwo_origin)
        rows = np.array([row for row, _, _ in pending], dtype=np.int64)
        columns = list(zip(*(groups for _, groups, _ in pending)))
        # pyarrow's C++ parser: about ten times faster than float() on each word
        values = np.stack([pa.array(column, type=pa.string()).cast(pa.float64())
                           .to_numpy(zero_copy_only=False) for column in columns])
        motion = _ffill(values[0], math.nan if self.motion is None else float(self.motion))
        if not np.isin(motion, (0.0, 1.0)).all():
            return False
        scale = INCH if self.inch else 1.0
        words = values[1:6].T.copy()
        words[:, :3] *= scale
        f_word = values[6]
        if (f_word <= 0).any():
            return False
        given = ~np.isnan(words)
        if self.tilt is not None and given[:, 3:].any():
            return False    # rotary words under G68.2: the word-by-word path says why
        prog = np.array(self.prog, dtype=float)
        if self.incremental:
            target = prog + np.cumsum(np.where(given, words, 0.0), axis=0)
        else:
            offset = np.add(self.g5x, self.g92)
            target = np.column_stack([_ffill(words[:, i] + offset[i], prog[i])
                                      for i in range(5)])
        if not (np.abs(target) <= MAX_COORDINATE).all():
            return False
        moving = given.any(axis=1)
        feed_rows = motion == 1.0
        if self.inverse_time:
            if np.isnan(f_word[moving & feed_rows]).any():
                return False
            feed = np.full(len(rows), self.feed)
        else:
            feed = _ffill(f_word * scale, self.feed)
            if np.isnan(feed[moving & feed_rows]).any():
                return False
        if moving.any():
            end = target[moving]
            start = np.concatenate([prog[None, :], end[:-1]])
            xyz = np.linalg.norm(end[:, :3] - start[:, :3], axis=1)
            rot = np.linalg.norm(end[:, 3:] - start[:, 3:], axis=1)
            rapid = motion[moving] == 0.0
            with np.errstate(divide="ignore", invalid="ignore"):
                if self.inverse_time:
                    duration = 60.0 / f_word[moving]
                    feed_s = np.full(end.shape[0], math.nan)
                else:
                    duration = 60.0 * np.where(xyz > 0, xyz, rot) / feed[moving]
                    feed_s = feed[moving] / 60.0
            duration[rapid] = math.nan
            feed_s[rapid] = math.nan
            k = end.shape[0]
            f_programmed = f_word[moving] if self.inverse_time else feed[moving]
            programmed = (np.where(rapid, 0, 1).astype(np.int8), end,
                          np.full((k, 3), math.nan), np.zeros(k, np.int8), np.zeros(k, np.int64),
                          np.full(k, self.inverse_time), np.where(rapid, math.nan, f_programmed),
                          rows[moving], np.full(k, self.tcp),
                          self.n_moves + np.arange(k, dtype=np.int64))
            self.add_many(end, rapid, duration, feed_s, rows[moving], programmed)
        self.motion = int(motion[-1])
        if not self.inverse_time:
            self.feed = float(feed[-1])
        return True

    def code_of(self, raw: str):
        """(code, comments) of a line: the code upper case without blanks and comments
        (None for a line that is skipped: empty, ``%``, or block-deleted)."""
        written = self.code_as_written(raw)
        if written is None:
            return None, []
        text, comments = written
        return text.upper().translate(_BLANKS), comments

    def block_text(self, raw: str) -> str | None:
        """A line's text without the blanks at its ends and its block-delete ``/``; None for a
        line that is skipped (empty, ``%``, or block-deleted)."""
        s = raw.strip()
        if not s or s[0] == "%":
            return None
        if s[0] == "/":
            if self.block_delete:
                return None
            s = s[1:]
        return s

    def code_as_written(self, raw: str):
        """(text, comments) of a line: the part that holds its code as written, comments
        blanked out in their places (so that a refusal can name a construct as written); None
        for a line that is skipped."""
        s = self.block_text(raw)
        if s is None:
            return None
        comments = []
        if ";" in s:
            # a ';' outside a ( ) comment makes the rest of the line a comment
            depth = 0
            for i, c in enumerate(s):
                if c == "(":
                    depth += 1
                elif c == ")":
                    depth -= 1
                elif c == ";" and depth <= 0:
                    s, rest = s[:i], s[i + 1:]
                    break
            else:
                rest = None
        else:
            rest = None
        if "(" in s or ")" in s:
            comments = _COMMENT.findall(s)
            s = _COMMENT.sub(lambda comment: " " * len(comment.group()), s)
            if "(" in s or ")" in s:
                self.refuse("unbalanced or nested '(' comment: close each comment with ')' "
                            "on its line, with no '(' inside", None, raw)
        if rest is not None:
            comments.append(rest)
        return s, comments

    def general(self, raw: str) -> bool:
        """Execute one line word by word (every construct, every error)."""
        prepared = self.prepare(raw, plain=False)
        return self._run_prepared(prepared)

    def _run_prepared(self, prepared) -> bool:
        """Act on a line as :meth:`prepare` classified it: skipped, kept as a comment, a
        settings line, or words to execute (their result)."""
        kind = prepared[0]
        if kind == _SKIP:
            if prepared[1]:
                self.skipped["/"] += 1
            return False
        if kind == _COMMENT:
            self.passthrough.append((self.row, prepared[1]))
            return False
        if kind == _SETTINGS:
            self.evaluate(prepared[1])
            return False
        if kind == _SINUMERIK:
            return self.sinumerik_block(*prepared[1:])
        _, code, traori, trafoof, text, comments = prepared
        words = (self.evaluate(code, text) if needs_macro_reader(code)
                 else self.tokens(code, text))
        return self.execute(words, traori, trafoof, text, comments)

    def tokens(self, code: str, line: str) -> list[tuple[str, float, str, str]]:
        """The words of a line's ``code``; a refusal names what ``line`` holds instead."""
        if "=" in code:
            at = code.find("=")
            self.refuse("'=' sets a parameter only after one (#1 = 5, #<depth> = -2)",
                        _word_at(code, max(at - 1, 0)), line)
        words, pos = [], 0
        for match in _WORD.finditer(code):
            if match.start() != pos:
                break
            number = match.group(2)
            words.append((match.group(1), float(number), number, match.group()))
            pos = match.end()
        if pos != len(code):
            self.refuse(*self.unreadable(line, code, pos, words), line)
        return words

    def unreadable(self, line: str, code: str, pos: int, words) -> tuple[str, str | None]:
        """(message, word) of a line's code that is no word from ``pos`` on (after ``words``):
        a name (``FINISH``, ``OFinal ToolPath``), a letter without its number, a malformed
        number, or another character."""
        char = code[pos]
        if char.isascii() and char.isalpha():
            name = self.name_at(line, code, pos)
            if name is not None:
                return _unknown_name(name), name
            bad = _word_at(code, pos)
            return f"cannot parse number {bad!r}", bad
        if char in "0123456789.+-" and words:
            bad = _word_at(code, pos - len(words[-1][3]))
            return f"cannot parse number {bad!r}", bad
        return f"cannot parse {_word_at(code, pos)!r}", None

    def name_at(self, line: str, code: str, pos: int) -> str | None:
        """The name written in ``line`` where ``code[pos]``, a letter, stands, when more letters
        follow it there (``FINISH``, ``OFinal ToolPath``: a program name after O is the rest
        of the line); None for a letter whose number is missing (``X`` in ``X Y1``), or when
        the code and the text cannot be lined up (a character whose upper case is longer)."""
        text, _ = self.code_as_written(line)
        places = [i for i, c in enumerate(text) if c not in _BLANK_CHARS]
        if "".join(text[i] for i in places).upper() != code:
            return None
        start = places[pos]
        name = _NAME.match(text, start)
        if name is None or len(name.group()) < 2:
            return None
        return text[start:].strip() if text[start] in "oO" else name.group()
