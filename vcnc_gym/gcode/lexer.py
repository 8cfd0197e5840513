"""Lexing G-code text into blocks of words, through pygcode.

A part program is read line by line (lines end at LF, CR LF or CR; a form
feed or vertical tab, which tapes and old posts put between sections, is
white space); each line is one block (RS-274/NGC,
Kramer, Proctor and Messina 2000, NIST IR 6556, section 3.3: an optional
block delete ``/``, an optional line number ``N``, words, comments).  The
lexing itself is pygcode's (``pygcode.Line``): it splits a line into its
block and comments (``( ... )`` and ``;`` to the end of the line, also in
the middle of a block), turns every word into a letter and a number
(``X10.``, ``X.5``, ``N0010``, ``G17.1`` all as written), and rejects what
RS-274/NGC rejects at this stage: a letter without a number, a number
without a letter, two numbers run together (``X1.2.3``), an unclosed
comment, two codes of one modal group in one block (``G17 G18``,
``G01 G02``) and a word given twice (``X1 X2``).

Why pygcode
-----------
Candidates tried on the same lines (arcs with R and I/J, comments in the
middle and at the end of a block, N numbers, Fanuc's trailing decimal point
``X10.``, malformed numbers):

- **gcodeparser** 0.3.0 (MIT, 2025): drops every word after a mid-block
  comment without a word (``G1 X1 (c) Y2`` gives only X1), reads
  ``G17.1`` as G17, gives ``True`` for a letter without a number and a
  TypeError-like crash for ``X10.``.  A reader that must never skip anything
  silently cannot sit on it.
- **GcodeTools** 0.3.2 (MIT, 2026): 3D-printer oriented, refuses R arcs
  outright (``NotImplementedError``).
- **nc-gcode-interpreter** 0.1.9 (Sinumerik dialect, pulls polars):
  comments only with ``;``, radius as ``CR=``; not RS-274's ``( )`` and R.
- **pygcode** 0.2.1 (GPL-3.0, 2017): every case above lexed as written or
  rejected with a message, modal groups known (LinuxCNC's table), two codes
  of one group in a block rejected.  Its one gap for RS-274 is an explicit
  plus sign (``Y+3``, legal in RS-274/NGC 3.3.2.1): we drop a ``+`` that
  directly follows a word's letter before handing the line over.  And it
  skips text it cannot read when another word follows (``X1.2.3 F10`` gives
  X1.2 F10), so every block is checked to be words and nothing else after
  pygcode has read it (``_check_covered``).

pygcode is the choice.  It is GPL-3.0 while vcnc-gym is MIT, so it is an
optional extra (``pip install vcnc-gym[gcode]``) imported only when a
program is read: the rest of the suite does not link it.  It has had no
release since 2017; the lexing surface we use (``Line``, ``Word``) is small
and covered by our tests, so a fork or a replacement is a one-module change.

Block delete: a ``/`` (or FANUC's optional block skip ``/1`` to ``/9``) that
starts a block is read with the switch off: the block runs, as on a control
whose block delete switch is off (RS-274/NGC 3.3; a ``/`` anywhere else is an
error naming the line).  The size of a program is checked before anything is
lexed: at most ``MAX_LINES`` lines of ``MAX_LINE_LENGTH`` characters.

What this module does not do: it gives no meaning to the words (that is
:mod:`vcnc_gym.gcode.interpreter`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = [
    "GCodeError",
    "Block",
    "Word",
    "lex",
    "split_lines",
    "check_size",
    "MAX_LINE_LENGTH",
    "MAX_LINES",
    "MAX_PROGRAM_BYTES",
]

#: Longest line read, characters: LinuxCNC's LINELEN = 255 (src/emc/rs274ngc/interp_internal.hh).  Checked for
#: every line before any is lexed.
MAX_LINE_LENGTH = 255

#: Most lines a program may have: 20 000 (a contour of 20 000 blocks is minutes of cutting at 100 mm/s with
#: 1 mm moves).  Checked before any line is lexed.  The work below the ceiling is long: on the 2-core CI host a
#: 10 000-chord program (4.6 m of path) is read in 7 s and its feed planned in 93 s (the look-ahead's
#: ~9 ms per knot span, vcnc_gym.motion.lookahead).
MAX_LINES = 20_000

#: Largest program read, bytes: MAX_LINES lines of MAX_LINE_LENGTH characters and a line end (5.1 MB).  A
#: file's size is checked before it is read.
MAX_PROGRAM_BYTES = MAX_LINES * (MAX_LINE_LENGTH + 2)


class GCodeError(ValueError):
    """A program that cannot be run, with the line (1-based, of the text) and the word at fault.

    Attributes
    ----------
    line : int or None
        Line of the program text, 1-based (None for the program as a whole).
    word : str or None
        The word or text at fault, as written.
    """

    def __init__(self, message: str, line: int | None = None, word: str | None = None, text: str | None = None):
        where = "" if line is None else f"line {line}" + (f" ({text.strip()!r})" if text else "") + ": "
        super().__init__(where + message)
        self.line = line
        self.word = word


@dataclass(frozen=True)
class Word:
    """One word of a block: its letter (upper case) and number, and the text it was written as."""

    letter: str
    value: float
    text: str


@dataclass(frozen=True)
class Block:
    """One line of the program with words.

    Attributes
    ----------
    line : int
        Line of the program text, 1-based.
    text : str
        The line as written.
    words : tuple of Word
        In the order written (comments removed).
    comment : str or None
        The line's comments, as pygcode joins them.
    """

    line: int
    text: str
    words: tuple
    comment: str | None

    def get(self, letter: str) -> Word | None:
        """The word with ``letter`` (upper case), or None (a block has each letter once but G and M)."""
        for w in self.words:
            if w.letter == letter:
                return w
        return None

    def all(self, letter: str) -> list[Word]:
        """Every word with ``letter`` (G and M may appear several times, from different modal groups)."""
        return [w for w in self.words if w.letter == letter]


# a "+" right after a word's letter (RS-274/NGC 3.3.2.1 allows it; pygcode's number pattern does not)
_PLUS = re.compile(r"(?<=[A-Za-z])(\s*)\+")
# the program start/end marker of a tape, "%" alone on a line (RS-274/NGC 3.3.1)
_PERCENT = re.compile(r"^\s*%\s*$")


# one word as RS-274/NGC writes it (after the "+" is dropped): a letter, a number
_WORD = re.compile(r"\s*([A-Za-z])\s*(-?(?:\d+\.?\d*|\.\d+))")


def _check_covered(block, number: int, raw: str) -> None:
    """GCodeError unless the block's text (comments removed) is words and nothing else: pygcode reads
    ``X1.2.3 F10`` as X1.2 F10, skipping text between two words that it would reject at the end."""
    text = (block._raw_text or "").strip()
    pos, count = 0, 0
    while pos < len(text):
        m = _WORD.match(text, pos)
        if m is None:
            rest = text[pos:].strip()
            if not rest:
                break
            hint = ": a block delete '/' must start the block (RS-274/NGC 3.3)" if rest.startswith("/") else ""
            raise GCodeError(
                f"cannot be lexed: {rest!r} is not a word (a letter and a number){hint}", number, rest.split()[0], raw
            )
        pos = m.end()
        count += 1
    if count != len(block.words):
        raise GCodeError(f"cannot be lexed: {count} words written, pygcode read {len(block.words)}", number, None, raw)


# a block delete (RS-274/NGC 3.3) or FANUC's optional block skip /1-/9 at the start of a block
_BLOCK_DELETE = re.compile(r"^\s*/[1-9]?")
# the line ends of a program text: LF, CR LF, CR (str.splitlines would also split at form feeds and \x1c-\x1e)
_LINE_END = re.compile(r"\r\n|\r|\n")
# white space that str.strip() knows and pygcode may not: form feed, vertical tab
_WHITE = str.maketrans({"\f": " ", "\v": " "})


def split_lines(text: str) -> list[str]:
    """The lines of a program text: split at LF, CR LF and CR only (a form feed is white space in a line)."""
    lines = _LINE_END.split(text)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


def check_size(text: str, name: str = "program") -> list[str]:
    """The lines of ``text``; GCodeError if it has more than ``MAX_LINES`` lines or a line longer than
    ``MAX_LINE_LENGTH`` characters (checked before anything is lexed: a fraction of a second for the largest)."""
    if len(text) > MAX_PROGRAM_BYTES:
        raise GCodeError(
            f"{name} has {len(text):,} characters: at most {MAX_PROGRAM_BYTES:,} are read "
            f"(MAX_LINES = {MAX_LINES:,} lines of MAX_LINE_LENGTH = {MAX_LINE_LENGTH} characters)"
        )
    lines = split_lines(text)
    if len(lines) > MAX_LINES:
        raise GCodeError(f"{name} has {len(lines):,} lines: at most MAX_LINES = {MAX_LINES:,} are read; split it")
    longest = max(range(len(lines)), key=lambda k: len(lines[k]), default=None)
    if longest is not None and len(lines[longest]) > MAX_LINE_LENGTH:
        raise GCodeError(
            f"the line has {len(lines[longest]):,} characters: at most MAX_LINE_LENGTH = "
            f"{MAX_LINE_LENGTH} (LinuxCNC's LINELEN)",
            longest + 1,
            None,
            lines[longest][:40] + "...",
        )
    return lines


def _pygcode():
    try:
        import pygcode
        import pygcode.exceptions
    except ImportError:  # pragma: no cover - the extra is in dev
        raise ImportError("reading G-code needs pygcode: pip install 'vcnc-gym[gcode]'") from None
    return pygcode


def lex(text: str) -> list[Block]:
    """The blocks of a program text (lines with words; blank, comment-only and ``%`` lines are skipped).

    Raises
    ------
    GCodeError
        For a line pygcode cannot lex: the message names the line, its text
        and pygcode's diagnosis (the word or the text left over).
    """
    if not isinstance(text, str):
        raise TypeError(f"program text must be a str, got {type(text).__name__}")
    lines = check_size(text)
    pygcode = _pygcode()
    blocks = []
    for number, raw in enumerate(lines, start=1):
        line = raw.translate(_WHITE)
        if not line.strip() or _PERCENT.match(line):
            continue
        skip = _BLOCK_DELETE.match(line)
        if skip is not None:  # block delete, switch off: the block runs
            line = " " * skip.end() + line[skip.end() :]
            if not line.strip():
                continue
        cleaned = _PLUS.sub(r"\1", line)
        depth = 0
        for ch in cleaned:
            if ch == ";" and depth == 0:
                break  # the rest of the line is a comment
            depth += (ch == "(") - (ch == ")")
            if depth not in (0, 1):
                break
        if depth:
            raise GCodeError("unbalanced comment parentheses", number, "(" if depth > 0 else ")", raw)
        try:
            parsed = pygcode.Line(cleaned)
        except (
            pygcode.exceptions.GCodeWordStrError,
            pygcode.exceptions.GCodeParameterError,
            pygcode.exceptions.GCodeBlockFormatError,
            AssertionError,
            ValueError,
        ) as e:
            detail = str(e)
            m = re.search(r"word '(\w)'|remaining '([^']*)'|-> (\w\S*)", detail)
            codes = re.findall(r": (\w[\d.]*)[{>]", detail)
            word = (m.group(1) or m.group(2) or m.group(3)).strip() if m else (" ".join(codes) or None)
            raise GCodeError(f"cannot be lexed: {detail} (pygcode)", number, word, raw) from None
        _check_covered(parsed.block, number, raw)
        if parsed.macro:
            raise GCodeError(f"'%' inside a block is not RS-274 (got {parsed.macro!r})", number, parsed.macro, raw)
        words = []
        for w in parsed.block.words:  # pyright: ignore[reportOptionalMemberAccess]  (a line with text has a block)
            try:
                value = float(w.value)
            except ValueError:  # O and T keep pygcode's text
                raise GCodeError(f"word {w.letter} needs a number, got {w.value!r}", number, str(w), raw) from None
            words.append(Word(w.letter, value, str(w)))
        words = tuple(words)
        comment = None if parsed.comment is None else str(parsed.comment.text)
        if words:
            blocks.append(Block(number, raw, words, comment))
    return blocks
