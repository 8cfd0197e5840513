"""vcnc_bench.options: vcnc-bench's program options that do not apply, or hold numbers the reader would refuse,
are errors naming the option."""

from __future__ import annotations

import argparse

import pytest

from vcnc_bench.options import DEFAULT_TOLERANCE, check_program_options, program_tolerance


def _args(**kw):
    base = {"program": None, "circle": None, "tolerance": None, "plants": None}
    return argparse.Namespace(**{**base, **kw})


@pytest.mark.parametrize("program", [None, ["butterfly"], ["circle-diamond-square"]])
def test_circle_without_the_iso_circle_program_is_an_error(program):
    with pytest.raises(ValueError, match="--circle D F sets the ISO 230-4 circle"):
        check_program_options(_args(program=program, circle=(50.0, 3000.0)))


def test_circle_with_the_iso_circle_program_is_accepted():
    for name in ("iso230-4", "iso230-4-ccw", "iso230-4-cw"):
        check_program_options(_args(program=[name], circle=(50.0, 3000.0)))


@pytest.mark.parametrize(
    "circle, option",
    [
        ((float("inf"), 3000.0), "--circle D"),
        ((50.0, float("nan")), "--circle F"),
        ((-50.0, 3000.0), "--circle D"),
        ((50.0, 0.0), "--circle F"),
        ((1e9, 3000.0), "--circle D"),
        ((50.0, 1e9), "--circle F"),
    ],
)
def test_a_circle_the_reader_would_refuse_is_an_error_naming_the_number(circle, option):
    with pytest.raises(ValueError, match=option):
        check_program_options(_args(program=["iso230-4"], circle=circle))


def test_tolerance_without_a_program_is_an_error():
    with pytest.raises(ValueError, match="--tolerance is the corner blending tolerance of --program"):
        check_program_options(_args(tolerance="0.05"))


@pytest.mark.parametrize("text", ["abc", "0", "-1", "inf", "nan"])
def test_a_bad_tolerance_is_an_error_naming_it(text):
    with pytest.raises(ValueError, match="--tolerance"):
        check_program_options(_args(program=["butterfly"], tolerance=text))


def test_tolerance_text_is_read_as_mm_or_sharp():
    assert program_tolerance(None) == DEFAULT_TOLERANCE
    assert program_tolerance("sharp") is None
    assert program_tolerance("0.05") == 0.05


def test_a_piece_name_that_is_also_a_local_file_is_an_error(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    check_program_options(_args(program=["butterfly"]))  # no such file here: the piece
    (tmp_path / "butterfly").write_text("G01 X1 F600\n")
    with pytest.raises(ValueError, match="names both a shipped test piece and the file 'butterfly'.*./butterfly"):
        check_program_options(_args(program=["butterfly"]))
    check_program_options(_args(program=["./butterfly"]))  # the file, named as one


def test_plants_with_a_program_is_an_error():
    with pytest.raises(ValueError, match="--plants N runs the robust evaluation of registered ids"):
        check_program_options(_args(program=["butterfly"], plants=4))


@pytest.mark.parametrize(
    "argv, names",
    [
        (["--env", "VCNC-Circle-v1", "--circle", "10", "1200"], "--circle"),
        (["--env", "VCNC-Circle-v1", "--tolerance", "0.02"], "--tolerance"),
        (["--program", "iso230-4", "--circle", "inf", "3000"], "--circle"),
        (["--program", "iso230-4", "--plants", "3"], "--plants"),
    ],
)
def test_vcnc_bench_refuses_an_option_that_does_not_apply_before_building_anything(argv, names, capsys):
    from vcnc_bench import cli

    with pytest.raises(SystemExit) as exc:
        cli.main(argv + ["--no-progress"])
    assert exc.value.code == 2
    assert names in capsys.readouterr().err
