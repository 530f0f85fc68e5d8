"""CLI conventions (issue 14, items 5 and 7): --version, help with examples, error lines, figures."""

from __future__ import annotations

import gc
import sys
from importlib.metadata import entry_points

import pytest
from support import MAP_FLAGS, cli, in_process, launch

import warpratchet
from warpratchet.cli import (
    EXAMPLES,
    SUBCOMMANDS,
    YOUNG_GENERATION_THRESHOLD,
    build_parser,
    console_main,
    main,
)


def test_version():
    done = cli("--version")
    assert done.returncode == 0 and done.stdout == f"warpratchet {warpratchet.__version__}\n"


def test_the_command_sets_the_cycle_collector_for_a_process_that_ends_with_it(monkeypatch, capsys):
    """The ``warpratchet`` command is ``console_main``: ``main`` with the collector's youngest
    generation collected less often (Warp's import makes ~10^5 objects that live to the end), then
    every object frozen out of the collector, which the interpreter's teardown would otherwise
    sweep over and over (``benchmarks/command_time.py``); ``main`` leaves a caller's process as it
    was."""
    (script,) = entry_points(group="console_scripts", name="warpratchet")
    assert script.value == "warpratchet.cli:console_main"
    monkeypatch.setattr(sys, "argv", ["warpratchet", "--version"])
    threshold, frozen = gc.get_threshold(), gc.get_freeze_count()
    assert main() == 0 and gc.get_freeze_count() == frozen and gc.get_threshold() == threshold
    try:
        assert console_main() == 0 and gc.get_freeze_count() > frozen
        assert gc.get_threshold() == (YOUNG_GENERATION_THRESHOLD, *threshold[1:])
    finally:
        gc.unfreeze()
        gc.set_threshold(*threshold)
    assert capsys.readouterr().out == f"warpratchet {warpratchet.__version__}\n" * 2


def test_top_level_help_describes_the_command_and_gives_examples(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "The ``warpratchet`` command." not in out  # the old one-liner
    assert "weak-chaos ratchet accelerator" in out and "examples:" in out
    for name in SUBCOMMANDS:
        assert f"    {name}" in out
    assert "warpratchet run --K 3 --b1 0.1 --b2 0.01" in out


@pytest.mark.parametrize("name", [n for n in SUBCOMMANDS if n != "figures"])
def test_every_subcommand_help_has_a_description_and_examples(name, capsys):
    assert main([name, "--help"]) == 0
    out = capsys.readouterr().out
    parser = build_parser()._subparsers._group_actions[0].choices[name]
    assert parser.description and len(parser.description) > 30
    assert "examples:" in out and all(line in out for line in EXAMPLES[name])


def test_parse_errors_are_a_short_usage_and_one_error_line_with_no_doubled_prefix(capfd):
    """argparse's convention (issue 14.7), kept short: one usage line, then the one error line."""
    done = in_process(capfd, "run", *MAP_FLAGS, "--points", "0", "--quiet")
    assert done.returncode == 2 and done.stdout == ""
    [usage, line] = done.stderr.strip().splitlines()
    assert line.startswith("warpratchet run: error: argument --points: points = 0 is outside")
    assert line.count("error:") == 1 and "warpratchet: error: warpratchet" not in line
    assert usage == "usage: warpratchet run [options]  (warpratchet run --help lists them)"


def test_a_one_line_argparse_usage_is_printed_as_it_is(capsys):
    assert main(["inspect"]) == 2
    usage, line = capsys.readouterr().err.splitlines()
    assert usage == "usage: warpratchet inspect [-h] [--json] archive"
    assert line == "warpratchet inspect: error: the following arguments are required: archive"


def test_errors_found_while_a_command_runs_are_one_line(capsys):
    assert main(["theory", "--K", "5", "--b1", "0.1", "--b2", "0.1"]) == 2
    assert capsys.readouterr().err == "warpratchet: error: K = 5.0 is outside the allowed range 0 < K < 4\n"


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["run", *MAP_FLAGS, "--threshold", "-1"], "threshold = -1.0 is outside"),
        (["sumrule", *MAP_FLAGS, "--threshold", "-0.5"], "threshold = -0.5 is outside"),
        (["sumrule", *MAP_FLAGS, "--m-max", "0"], "m_max = 0 is outside"),
        (["sweep", "--path", "maximal", "--b2", "0.01:0.02:2", "--threshold", "-1"], "threshold = -1.0"),
        (["run", *MAP_FLAGS, "--rerun-points", "0"], "rerun_points = 0 is outside"),
    ],
)
def test_every_range_is_checked(argv, needle, capsys):
    assert main([*argv, "--quiet"]) == 2
    usage, line = capsys.readouterr().err.splitlines()
    assert usage.startswith("usage: warpratchet ") and needle in line


def test_figures_subcommand_is_the_viz_command(tmp_path, capsys):
    assert main(["figures", "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: warpratchet figures") and "--quick" in out
    assert main(["figures", "--only", "fig99", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("warpratchet figures: error: --only 'fig99'") and err.count("\n") == 1


def test_figures_without_matplotlib_is_one_clear_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` raises ImportError
    assert main(["figures", "--only", "fig3", "--out", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err
    assert err == (
        "warpratchet figures: error: matplotlib is needed for the figures: "
        "pip install 'warpratchet[figures]'\n"
    )
    assert not (tmp_path / "f").exists()


def test_the_command_starts_without_importing_warp():
    """--help and --version answer without Warp (a fast start, and little for Ctrl-C to hit)."""
    code = "import sys; from warpratchet.cli import main; main(['--version']); print('warp' in sys.modules)"
    done = __import__("subprocess").run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=900
    )
    assert done.stdout.splitlines()[-1] == "False", done.stderr


def test_a_reader_that_leaves_early_is_not_an_error():
    """``warpratchet orbits ... | head``: the pipe closes while the command still writes; it stops
    quietly with the shell's status for SIGPIPE (141), no error line, no traceback."""
    proc = launch("orbits", *MAP_FLAGS, "--period", "6", "--json", text=False)
    assert proc.stdout.read(10) == b'{"K": 3.0,'
    proc.stdout.close()  # ~300 kB are still to come: the next writes meet a closed pipe
    assert proc.wait(timeout=900) == 141
    assert proc.stderr.read() == b""


def test_figures_help_has_examples_too(capsys):
    """README: every ``warpratchet COMMAND --help`` describes its options with examples."""
    assert main(["figures", "--help"]) == 0
    out = capsys.readouterr().out
    assert "examples:" in out and "warpratchet figures --all --out figures/" in out


@pytest.mark.parametrize("name", ["run", "sweep"])
def test_threshold_help_names_the_rule_that_sets_its_default(name, capsys):
    """With --threshold-rule positive the default is (1 + ln n)/n, not the strict rule's 10 (1 + ln n)/n."""
    assert main([name, "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split("options:")[1].split())
    threshold = out[out.index("--threshold THRESHOLD") : out.index("--threshold-rule {")]
    assert "--threshold-rule" in threshold and "10 (1 + ln n)/n)" not in threshold
