"""The G-code reader on programs as CAM systems and old controls write them, and on bad or huge ones.

Each case is judged against an independent expectation written here: the geometry of the moves (lengths
by hand), the line a message must name, the time a refusal may take.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from vcnc_gym.gcode import GCodeError, lex, load_text, read_program, read_program_text
from vcnc_gym.gcode.feeds import KINK_ANGLE
from vcnc_gym.gcode.interpreter import MAX_COORDINATE, ZERO_LENGTH
from vcnc_gym.gcode.lexer import MAX_LINE_LENGTH, MAX_LINES, MAX_PROGRAM_BYTES


# -- absolute thresholds -----------------------------------------------------------------------------------------
def test_a_half_millimetre_move_is_kept_whatever_the_largest_word():
    # R99999 (99.999 m, in range) on an arc; the 0.5 mm G01 must stay a move
    text = "G21 G90 G17\nG01 X10 Y0 F600\nG01 X10.5 Y0\nG02 X10.5 Y-1 R99999\n"
    program = read_program_text(text)
    lengths = [m.length for m in program.moves]
    assert lengths[1] == pytest.approx(0.5, abs=1e-12)
    assert not program.warnings


def test_a_tenth_of_a_micrometre_move_is_kept_after_a_far_rapid():
    program = read_program_text("G00 X90000\nG01 X90000.0001 F600\nG01 X90001\n")
    assert program.moves[0].length == pytest.approx(1e-4, rel=1e-6)  # 0.1 um, well above ZERO_LENGTH
    assert not program.warnings


def test_a_move_below_one_nanometre_is_dropped_with_its_line_named():
    with pytest.warns(UserWarning, match="line 2"):
        program = read_program_text(f"G01 X1 F600\nG01 X{1 + ZERO_LENGTH / 2:.10f}\nG01 X2\n")
    assert len(program.moves) == 2 and "line 2" in program.warnings[0]


@pytest.mark.parametrize("word", ["R1000000000", "X" + "9" * 200, "I-200000", "F2000000"])
def test_a_number_out_of_range_is_named_by_line_and_word(word):
    letter = word[0]
    text = {
        "R": f"G01 X1 F600\nG02 X2 Y0 {word}\n",
        "X": f"G01 {word} F600\n",
        "I": f"G01 X1 F600\nG02 X2 {word}\n",
        "F": f"G01 X1 {word}\n",
    }[letter]
    with pytest.raises(GCodeError) as exc:
        read_program_text(text)
    assert exc.value.word is not None and exc.value.word.startswith(letter)
    assert exc.value.line == text.count("\n", 0, text.index(word)) + 1
    assert str(MAX_COORDINATE)[:3] in str(exc.value) or "mm/min" in str(exc.value)


# -- as CAM writes it -----------------------------------------------------------------------------------------
def _chords(radius: float, chord: float, sweep_deg: float) -> str:
    """An arc of ``radius`` written as G01 chords of about ``chord`` mm (what a CAM post does)."""
    n = max(2, round(math.radians(sweep_deg) * radius / chord))
    angles = np.linspace(0.0, math.radians(sweep_deg), n + 1)
    lines = [f"G00 X{radius:.4f} Y0.0000", "G01 F3000"]
    lines += [f"G01 X{radius * math.cos(a):.4f} Y{radius * math.sin(a):.4f}" for a in angles[1:]]
    return "\n".join(lines) + "\n"


def test_chords_of_an_arc_with_sub_degree_kinks_are_run_through():
    # 1 mm chords of a 100 mm arc: kinks of 0.57 degrees, whose 10 um blends would not fit in the chords
    sweep = math.radians(10.0)
    toolpath = read_program(_chords(100.0, 1.0, 10.0), 0.01)
    kinds = {j.kind for j in toolpath.joints}
    assert kinds == {"kink"}
    n = round(sweep * 100.0)  # 17 chords of 2 R sin(sweep / 2n) each
    expected = n * 2.0 * 100.0 * math.sin(sweep / (2 * n))
    assert toolpath.length == pytest.approx(expected, rel=1e-4)
    assert max(j.angle for j in toolpath.joints) <= KINK_ANGLE
    profile = toolpath.feedrate_profile()  # the look-ahead plans it without a stop at the kinks
    assert len(toolpath.stops) == 0 and profile is not None


def test_a_corner_above_the_kink_angle_whose_blend_does_not_fit_is_an_error_naming_the_move():
    text = "G01 X1 F600\nG01 X2 Y0.1\nG01 X3 Y0.1\n"  # 5.7 degrees on 1 mm moves at a 1 mm tolerance
    with pytest.raises(GCodeError, match="do not fit") as exc:
        read_program(text, 1.0)
    assert exc.value.line in (1, 2, 3)


def test_block_delete_runs_the_block_as_with_the_switch_off():
    plain = read_program_text("G01 X1 F600\nG01 X2 Y1\n")
    deleted = read_program_text("/G01 X1 F600\n/1 G01 X2 Y1\n/\n/ (note)\n")
    assert [m.end.tolist() for m in deleted.moves] == [m.end.tolist() for m in plain.moves]


def test_a_block_delete_in_the_middle_of_a_block_is_named_by_line():
    with pytest.raises(GCodeError, match="must start the block") as exc:
        read_program_text("G01 X1 F600\nN20 /G01 X2\n")
    assert exc.value.line == 2


def test_form_feeds_are_white_space_and_do_not_shift_line_numbers():
    text = "\fG01 X1 F600 (part\fone)\n\f\nG01 X2 Y1 ;end\fof\nG01 X1e\n"
    with pytest.raises(GCodeError) as exc:
        read_program_text(text)
    assert exc.value.line == 4  # the form feeds split no line
    blocks = lex(text.rsplit("\n", 2)[0] + "\n")
    assert [b.line for b in blocks] == [1, 3] and blocks[0].comment == "part one"


def test_a_latin_1_comment_in_a_file_is_read(tmp_path):
    path = tmp_path / "part.nc"
    path.write_bytes("G01 X1 F600 (Fr\u00e4ser 6 mm)\nG01 X2 Y1\n".encode("latin-1"))
    program = read_program_text(load_text(path)[0])
    assert len(program.moves) == 2


def test_a_non_utf8_byte_outside_a_comment_is_named_by_line(tmp_path):
    path = tmp_path / "part.nc"
    path.write_bytes(b"G01 X1 F600\nG01 X2 \xe4Y1\n")
    with pytest.raises(GCodeError) as exc:
        read_program_text(load_text(path)[0])
    assert exc.value.line == 2


# -- sizes: documented ceilings, checked before the work -------------------------------------------------------
def test_a_file_above_the_size_ceiling_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "huge.nc"
    with open(path, "wb") as f:
        f.truncate(8 * 1024**3)  # 8 GiB, sparse: nothing is written, nothing may be read
    t0 = time.perf_counter()
    with pytest.raises(GCodeError, match="MAX_PROGRAM_BYTES"):
        load_text(path)
    assert time.perf_counter() - t0 < 1.0
    assert MAX_PROGRAM_BYTES < 8 * 1024**3


def test_a_program_with_too_many_lines_is_refused_before_lexing():
    text = "G01 X1 F600\n" + "G01 X2\nG01 X1\n" * (MAX_LINES // 2 + 1)
    t0 = time.perf_counter()
    with pytest.raises(GCodeError, match="MAX_LINES"):
        read_program_text(text)
    assert time.perf_counter() - t0 < 1.0


def test_a_ten_megabyte_line_is_refused_before_lexing():
    t0 = time.perf_counter()
    with pytest.raises(GCodeError, match="MAX_PROGRAM_BYTES|MAX_LINE_LENGTH"):
        lex("G01 X" + "1" * 10_000_000)
    with pytest.raises(GCodeError, match="MAX_LINE_LENGTH") as exc:
        lex("G01 X1 F600\n(" + "c" * MAX_LINE_LENGTH + ")\n")
    assert exc.value.line == 2
    assert time.perf_counter() - t0 < 1.0


def test_a_path_too_long_for_the_look_ahead_names_its_length_not_an_argument():
    text = "G01 X10000 F6000\nG01 X10000 Y10000\nG01 X0 Y10000\n"  # 30 m
    with pytest.raises(GCodeError, match="30000 mm long") as exc:
        read_program(text, 0.01)
    assert "pass a larger spacing" not in str(exc.value)


def test_an_unreadable_program_file_is_named(tmp_path, monkeypatch):
    import vcnc_gym.gcode as gcode

    path = tmp_path / "part.nc"
    path.write_text("G01 X1 F600\n")

    def refuse(*args, **kwargs):  # what open() raises on a file without read permission (root reads any)
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(gcode, "open", refuse, raising=False)
    with pytest.raises(GCodeError, match="part.nc.*cannot be read: Permission denied"):
        load_text(path)


def test_a_folder_given_as_a_program_file_is_named(tmp_path):
    folder = tmp_path / "part.nc"
    folder.mkdir()
    with pytest.raises((GCodeError, FileNotFoundError), match="part.nc"):
        load_text(folder)


def test_a_program_name_that_is_no_file_and_no_g_code_lists_the_shipped_pieces():
    import gymnasium as gym

    import vcnc_gym  # noqa: F401

    with pytest.raises(GCodeError, match="neither a file, a test piece .*iso230-4-ccw"):
        gym.make("VCNC-GCode-v1", program="iso230-4")


@pytest.mark.parametrize(
    "name, value",
    [("tolerance", True), ("tolerance", "0.01"), ("acceleration", "1000"), ("jerk", False), ("spacing", 0)],
)
def test_read_program_numbers_go_through_validation(name, value):
    kwargs = {"tolerance": 0.01, name: value}
    with pytest.raises(ValueError, match=name):
        read_program("G01 X1 F600\n", **kwargs)


def test_a_corner_sharper_than_the_blend_design_reaches_is_named_by_line():
    # the path turns back by 179.98 degrees (not a full U-turn): found by tests/probes/fuzz_new_surfaces.py
    text = "G01 X10 Y0 F600\nG01 X0 Y0.0036\n"
    with pytest.raises(GCodeError, match="cannot be blended") as exc:
        read_program(text, 0.01)
    assert exc.value.line == 2
