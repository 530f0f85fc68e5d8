"""The `warpratchet theory` and `warpratchet run` commands, and every bad-input path of the core API."""

import json
import math

import numpy as np
import pytest
from support import cli, error_line, in_process

from warpratchet import theory
from warpratchet.cli import main
from warpratchet.ensemble import Ensemble
from warpratchet.params import MapParams

RUN_KEYS = {
    "K",
    "b1",
    "b2",
    "points",
    "steps",
    "seed",
    "A",
    "A_stderr",
    "lyapunov",
    "lyapunov_min",
    "chaotic_fraction",
    "seconds",
    "point_steps_per_second",
}
THEORY_KEYS = {"K", "b1", "b2", "l1", "l2", "c", "domain", "S_L", "S_R", "S_C", "A"}


def test_theory_json(capsys):
    assert main(["theory", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == THEORY_KEYS
    assert out["domain"] == "LR"
    assert out["A"] == theory.acceleration_both_islands(0.1, 0.01)
    assert main(["theory", "--K", "2.5", "--b1", "0.1", "--b2", "0.01", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["A"] is None and out["S_C"] is None and out["domain"] in ("LR", "L", "R", "none")


def test_acceptance_run_agrees_with_theory(capfd):
    """Issue acceptance: the documented command, in a subprocess, against `warpratchet theory` (in
    this process)."""
    run = cli(
        "run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "10000", "--steps", "120000", "--json"
    )
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""  # the progress bar is drawn only on a terminal
    report = json.loads(run.stdout)
    assert RUN_KEYS <= set(report)
    th = json.loads(in_process(capfd, "theory", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--json").stdout)
    # Strip ensemble (the paper's protocol): bias bound as in test_statistics' strip test.
    excluded = report["points"] - report["chaotic_points"]
    bias = 200 / report["steps"] + 2 * excluded / report["chaotic_points"]
    assert abs(report["A"] - th["A"]) < 4 * report["A_stderr"] + bias
    assert report["chaotic_fraction"] > 0.999 and report["lyapunov"] > 0.1


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["run", "--K", "5", "--b1", "0.1", "--b2", "0.01"], "K = 5.0"),
        (["run", "--K", "3", "--b1", "-0.1", "--b2", "0.01"], "b1 = -0.1"),
        (["run", "--K", "3", "--b1", "0.6", "--b2", "0.5"], "b1 + b2"),
        (["run", "--K", "nan", "--b1", "0.1", "--b2", "0.01"], "K = nan"),
        (["run", "--K", "3", "--b1", "abc", "--b2", "0.01"], "'abc'"),
        (["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "0"], "--points"),
        (["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--steps", "-5"], "--steps"),
        (["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--threads", "0"], "--threads"),
        (["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--init", "disk"], "--init"),
        (["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--device", "tpu:0"], "tpu"),
        (["run", "--b1", "0.1", "--b2", "0.01"], "--K"),
        (["theory", "--K", "0", "--b1", "0.1", "--b2", "0.01"], "K = 0.0"),
        (["bogus"], "bogus"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_no_traceback(args, needle, capfd):
    """Through the command's main in this process: a traceback would be an exception raised here."""
    result = in_process(capfd, *args, "--quiet") if args[0] == "run" else in_process(capfd, *args)
    assert result.returncode == 2, result.stderr
    line = error_line(result.stderr)  # after a short usage line if refused while parsing
    assert needle in line
    assert "Traceback" not in result.stderr and result.stdout == ""


def test_human_output_and_quiet(capsys):
    assert (
        main(
            ["run", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "500", "--steps", "500", "--quiet"]
        )
        == 0
    )
    captured = capsys.readouterr()
    assert "A" in captured.out and "theory" in captured.out
    assert captured.err == ""


def test_api_bad_inputs():
    p = MapParams(3.0, 0.1, 0.01)
    with pytest.raises(ValueError, match="points = 0"):
        Ensemble.sample(p, 0)
    with pytest.raises(ValueError, match="seed = -1"):
        Ensemble.sample(p, 10, seed=-1)
    with pytest.raises(ValueError, match="init = 'disk'"):
        Ensemble.sample(p, 10, "disk")
    with pytest.raises(ValueError, match="threads = 0"):
        Ensemble.sample(p, 10, threads=0)
    with pytest.raises(ValueError, match="equal length"):
        Ensemble(p, np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match="finite"):
        Ensemble(p, np.array([math.nan]), np.zeros(1))
    ens = Ensemble.sample(p, 10)
    with pytest.raises(ValueError, match="steps = -1"):
        ens.run(-1)
    with pytest.raises(ValueError, match="chunk_steps = 0"):
        ens.run(10, chunk_steps=0)
    with pytest.raises(ValueError, match="missing fields"):
        Ensemble.from_state(p, {"x": np.zeros(3)}, 0)
    from warpratchet.observables import finite_time_acceleration

    with pytest.raises(ValueError, match="step = 0"):
        finite_time_acceleration(ens.state(), 0)


def test_samplers_are_seeded_and_in_range():
    p = MapParams(3.0, 0.1, 0.05)
    a = Ensemble.sample(p, 1000, "strip", seed=9).state()
    b = Ensemble.sample(p, 1000, "strip", seed=9).state()
    np.testing.assert_array_equal(a["x"], b["x"])
    in_strip = (a["x"] <= p.b1) | (a["x"] >= 1 - p.b2)
    assert in_strip.all()
    g = Ensemble.sample(p, 1000, "grid").state()
    assert g["x"].size == 31 * 31
    assert not np.any(np.isin(g["x"], [p.b1, 1 - p.b2]))
