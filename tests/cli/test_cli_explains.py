"""Output that explains itself: what ``+-`` is, the units, the distance to the closed form, the
threshold behind "chaotic", why a closed form is absent; help without a command; counts in
scientific notation; a near-miss flag named; what ``--rerun`` wrote."""

from __future__ import annotations

import json
import re

import pytest
from support import MAP_FLAGS, error_line

from warpratchet.cli import build_parser, main

SMALL = ["--points", "300", "--steps", "300", "--quiet"]


def test_bare_command_prints_the_help(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: warpratchet") and "theory" in out and "examples:" in out


@pytest.mark.parametrize(("text", "value"), [("1e5", 100000), ("2.5e3", 2500), ("120000", 120000)])
def test_counts_accept_integral_scientific_notation(text, value):
    args = build_parser().parse_args(["run", *MAP_FLAGS, "--steps", text, "--points", text])
    assert args.steps == value == args.points


@pytest.mark.parametrize("text", ["1.5", "1e-3", "2.5e0", "inf", "many"])
def test_counts_refuse_what_is_not_a_whole_number(text, capsys):
    assert main(["run", *MAP_FLAGS, "--steps", text]) == 2
    assert f"--steps: invalid integer value: '{text}'" in error_line(capsys.readouterr().err)


@pytest.mark.parametrize(
    ("argv", "hint"),
    [
        (["run", "--k", "3", "--b1", "0.1", "--b2", "0.01"], "did you mean --k -> --K?"),
        (["run", *MAP_FLAGS, "--point", "5", "--stpes", "10"], "did you mean --stpes -> --steps?"),
        (["theory", "--K", "3", "--B1", "0.1", "--b2", "0.01"], "did you mean --B1 -> --b1?"),
    ],
)
def test_a_near_miss_flag_is_named(argv, hint, capsys):
    assert main(argv) == 2
    assert error_line(capsys.readouterr().err).endswith(hint)


def test_theory_says_why_a_closed_form_is_absent(capsys):
    assert main(["theory", "--K", "2.99", "--b1", "0.1", "--b2", "0.01"]) == 0
    lines = capsys.readouterr().out.splitlines()
    a_line = next(line for line in lines if line.strip().startswith("A ="))
    assert "n/a (the closed forms of Sec. IV hold at K = 3 only, not K = 2.99" in a_line
    assert main(["theory", "--K", "3", "--b1", "0.45", "--b2", "0.45"]) == 0  # domain none
    assert "domain none" in capsys.readouterr().out


def test_run_names_the_error_units_distance_and_threshold(capsys):
    assert main(["run", *MAP_FLAGS, *SMALL, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert main(["run", *MAP_FLAGS, *SMALL]) == 0
    out = capsys.readouterr().out
    assert re.search(r"A += \S+ \+- \S+ /iteration \(\+- one standard error", out), out
    z = (report["A"] - report["A_theory"]) / report["A_stderr"]
    want = f"theory      = {report['A_theory']:.6g} /iteration, Eq. (Aa): A - theory = {z:+.2f} standard"
    assert want in out
    assert f"FTLE > {report['threshold']:.3g} = 10 (1 + ln n)/n at n = 300 (rule strict)" in out


def test_run_away_from_K3_says_there_is_no_closed_form(capsys):
    assert main(["run", "--K", "2.99", "--b1", "0.1", "--b2", "0.01", *SMALL]) == 0
    assert "theory      : none at K != 3" in capsys.readouterr().out


def test_rerun_reports_frames_and_size(tmp_path, capsys):
    pytest.importorskip("rerun", reason="the rerun extra is not installed")
    out = tmp_path / "run.rrd"
    assert main(["run", *MAP_FLAGS, *SMALL, "--rerun", str(out)]) == 0
    size = out.stat().st_size / 1e6
    line = next(line for line in capsys.readouterr().out.splitlines() if "wrote" in line)
    assert re.fullmatch(rf"  wrote {re.escape(str(out))}: \d+ frames, {size:.1f} MB \(view: rerun .*\)", line)


def test_a_small_run_prints_a_rate_that_is_not_zero(capsys):
    """The rate keeps three significant digits: a small run prints ``0.45 M``, not ``0 M``."""
    assert main(["run", *MAP_FLAGS, *SMALL]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if "point-steps/s" in line)
    match = re.fullmatch(r"  \d+\.\d\d s, (\S+) M point-steps/s", line)
    assert match and float(match.group(1)) > 0, line
