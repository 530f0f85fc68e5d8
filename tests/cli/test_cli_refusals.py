"""What the command refuses, subcommand by subcommand, in one table (issue 13 item 7, issue 14.7).

Every row is a command line that must end with exit status 2, nothing on stdout and one error line
(after a short usage line when argparse refuses a flag while parsing) that contains the row's
needle: the value, and the allowed range or the reason. Rows that fail later, while the command
runs, are in the tests of that command (e.g. tests/cli/test_inputs.py).

The rows of ``run`` are issue 13's: 2^32 steps in one chunk ran 0 steps (a 32-bit count) and
reported success (item 1); the other values were accepted (item 7).
"""

from __future__ import annotations

import pytest
from support import MAP_FLAGS, error_line

from warpratchet.cli import main

RUN = ["run", *MAP_FLAGS, "--points", "8", "--steps", "8"]
SUMRULE = ["sumrule", *MAP_FLAGS, "--points", "10"]
MAXIMAL = ["sweep", "--path", "maximal"]
GRID = ["sweep", "--grid"]

REFUSED = [
    ([*RUN, "--chunk-steps", "4294967296"], "--chunk-steps: chunk_steps = 4294967296 is outside"),
    ([*RUN, "--threads", "1000000000"], "--threads: threads = 1000000000 is outside"),
    ([*RUN, "--threshold", "nan"], "--threshold: threshold = nan is not finite"),
    ([*RUN, "--threshold", "-1"], "--threshold: threshold = -1.0 is outside"),
    ([*RUN, "--points", "1.5"], "--points: invalid integer value: '1.5'"),
    ([*SUMRULE, "--grid", "4"], "not allowed with argument"),
    ([*SUMRULE, "--steps", "100"], "steps = 100"),
    (["sumrule", "--K", "5", "--b1", "0.1", "--b2", "0.01", "--points", "10"], "K = 5.0"),
    ([*SUMRULE, "--classifier", "nope"], "invalid choice"),
    ([*MAXIMAL, "--b2", "0.01:0.1"], "--b2 '0.01:0.1' is not START:STOP:COUNT"),
    ([*MAXIMAL, "--b2", "0.01:0.1:0"], "COUNT = 0 is outside the allowed range"),
    ([*MAXIMAL, "--b2", "0.01:0.1:1"], "COUNT = 1 cannot include both ends"),
    ([*MAXIMAL, "--b2", "x:0.1:3"], "--b2 'x:0.1:3'"),
    ([*MAXIMAL, "--b2", "0.01:0.3:3"], "b2 = 0.3 is outside the maximal path's range"),
    (MAXIMAL, "--path maximal needs --b2"),
    ([*MAXIMAL, "--b2", "0.1", "--b1", "0.2"], "--b1 is not used by --path maximal"),
    (["sweep", "--path", "line", "--b2", "0.01:0.1:3"], "--path line needs --a"),
    (["sweep", "--path", "k", "--Ks", "1:5:3", "--b1", "0.1", "--b2", "0.01"], "K = 5.0 is outside"),
    (["sweep", "--path", "k", "--Ks", "2:3:3", "--b1", "0.1", "--b2", "0.01:0.02:2"], "a single value"),
    ([*GRID, "b1=0.1:0.2:3"], "needs both b1=START:STOP:COUNT and b2="),
    ([*GRID, "b1=0.1:0.2:3,b3=0.1:0.2:3"], "--grid 'b1=0.1:0.2:3,b3=0.1:0.2:3' is not"),
    ([*GRID, "b1=0.1:0.2:3,b2=0.01:0.02:inf"], "--grid b2 '0.01:0.02:inf'"),
    ([*GRID, "b1=0.1:0.2:3,b2=0.01:0.02:3", "--domain", "LR,X"], "'X'"),
    ([*GRID, "b1=0.6:0.9:3,b2=0.5:0.9:3"], "has no point with b1 + b2 < 1"),
    ([*MAXIMAL, "--grid", "b1=0.1:0.2:3,b2=0.1:0.2:3"], "not allowed with argument"),
]


@pytest.mark.parametrize(("argv", "needle"), REFUSED, ids=[" ".join(argv) for argv, _ in REFUSED])
def test_refused_in_one_line_naming_the_value(argv, needle, capsys):
    code = main([*argv, "--quiet"])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == "", captured.err
    assert needle in error_line(captured.err), captured.err
