"""``warpratchet run --transport``: the JSON keys, the archive's /transport group, exact resume.

A run killed (SIGKILL) partway and run again with the same command must end with the same
histograms, carry state, spread rows and report as one that was never interrupted, bit for bit.
"""

from __future__ import annotations

import json
import signal
import time

import numpy as np
from support import MAP_FLAGS, archive_rows, in_process, launch, refused, same_history
from support import documented_names as _documented_names
from support import documented_optional as _documented_optional
from support import written_names as _written_names

from warpratchet import MapParams
from warpratchet.archive import open_archive, verify_archive
from warpratchet.transport import CARRY_FIELDS, TransportEnsemble

POINTS, SEED, STEPS = 1500, 7, 24_000  # 240 chunks: killed after 40
RUN = ["run", *MAP_FLAGS, "--points", str(POINTS), "--seed", str(SEED), "--steps", str(STEPS)]
RUN += ["--chunk-steps", "100", "--checkpoint-every", "500", "--quiet", "--json", "--transport"]


def test_json_has_the_histograms_mu_and_tail_exponents(capfd):
    proc = in_process(
        capfd, "run", *MAP_FLAGS, "--points", "500", "--steps", "3000", "--quiet", "--json", "--transport"
    )
    assert proc.returncode == 0, proc.stderr
    t = json.loads(proc.stdout)["transport"]
    assert set(t["return_times"]) == {"edges", "counts", "open"}
    assert set(t["flights"]) == {"edges", "counts_plus", "counts_minus", "open_plus", "open_minus"}
    assert len(t["return_times"]["edges"]) == len(t["return_times"]["counts"]) + 1
    assert t["return_times"]["edges"][:3] == [1, 2, 4]
    assert isinstance(t["mu"], float) and isinstance(t["mu_stderr"], float) and t["mu_fit"]["groups"] == 16
    assert set(t["tail_exponents"]) == {"return_times", "flights_plus", "flights_minus"}
    ens = TransportEnsemble.sample(MapParams(3.0, 0.1, 0.01), 500, "strip", 0)
    ens.run(3000)
    h = ens.histograms()
    assert t["return_times"]["counts"] == h.return_times[: len(t["return_times"]["counts"])].tolist()
    assert t["flights"]["counts_plus"] == h.flights_plus[: len(t["flights"]["counts_plus"])].tolist()
    text = in_process(
        capfd, "run", *MAP_FLAGS, "--points", "500", "--steps", "3000", "--quiet", "--transport"
    ).stdout
    assert "mu          =" in text and "flights +" in text and "returns" in text


def test_a_killed_run_resumed_equals_an_uninterrupted_one_bit_for_bit(tmp_path, capfd):
    """The run killed in a fresh process; the same command again and the reference in this one."""
    whole, killed = str(tmp_path / "whole.h5"), str(tmp_path / "killed.h5")
    proc = launch(*RUN, "--out", killed)
    start = time.monotonic()
    while proc.poll() is None and archive_rows(killed) < 40 and time.monotonic() - start < 900:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=900)
    with open_archive(killed) as arc:
        assert 0 < arc.checkpoint_step < STEPS  # killed partway, with a checkpoint to resume from
    again = in_process(capfd, *RUN, "--out", killed)
    reference = in_process(capfd, *RUN, "--out", whole)
    assert again.returncode == 0 and reference.returncode == 0, again.stderr + reference.stderr
    got, expected = json.loads(again.stdout), json.loads(reference.stdout)
    assert got["transport"] == expected["transport"] and got["A"] == expected["A"]
    with open_archive(killed) as a, open_archive(whole) as b:
        assert a.features == b.features == ("history", "transport")  # run keeps its history too
        assert same_history(a.history, b.history)  # rows, block records and subsample
        for name in ("step", "counts"):
            np.testing.assert_array_equal(a.transport[name], b.transport[name])
        ea, eb = a.ensemble(), b.ensemble()
        ta, tb = ea.transport_state(), eb.transport_state()
        np.testing.assert_array_equal(ta.counts, tb.counts)
        np.testing.assert_array_equal(ta.spread, tb.spread)
        for name in CARRY_FIELDS:
            np.testing.assert_array_equal(ta.carry[name], tb.carry[name])
        assert ea.step == STEPS and a.transport["step"][-1] == STEPS
        np.testing.assert_array_equal(a.transport["counts"][-1], ta.counts)
    assert verify_archive(killed)[0] == []


def test_transport_and_plain_archives_are_different_runs(tmp_path, capfd):
    out = str(tmp_path / "run.h5")
    small = ["run", *MAP_FLAGS, "--points", "100", "--steps", "300", "--quiet", "--out", out]
    assert in_process(capfd, *small).returncode == 0
    assert "(transport is False in the file, True requested)" in refused(capfd, [*small, "--transport"])


def test_docs_match_a_transport_archive(tmp_path, capfd):
    """docs/archive.md lists exactly what a transport archive writes (the plain names: test_archive)."""
    out = tmp_path / "run.h5"
    small = ["run", *MAP_FLAGS, "--points", "100", "--steps", "300", "--quiet", "--transport", "--out"]
    assert in_process(capfd, *small, str(out)).returncode == 0
    documented, written = _documented_names(), _written_names(out)
    assert {name for name in documented if name.startswith("/transport")} >= {"/transport/b/spread"}
    assert documented - written <= _documented_optional(), "documented but not written"
    assert written - documented == set(), "written but not documented"


def test_mu_counts_the_chaotic_points_of_the_runs_threshold_rule(tmp_path, capfd):
    """``--threshold-rule positive`` classifies the spread's points as History does, also after a
    resume from the archive (the spread used to take the strict rule whatever the run's)."""
    args = (*MAP_FLAGS, "--points", "2000", "--quiet", "--json", "--transport")
    args = (*args, "--threshold-rule", "positive")
    whole = json.loads(in_process(capfd, "run", *args, "--steps", "3000").stdout)["transport"]
    path = str(tmp_path / "t.h5")
    assert in_process(capfd, "run", *args, "--steps", "1500", "--out", path).returncode == 0
    resumed = json.loads(in_process(capfd, "run", *args, "--steps", "3000", "--out", path).stdout)[
        "transport"
    ]
    mu = {}
    for rule in ("strict", "positive"):
        ens = TransportEnsemble.sample(MapParams(3.0, 0.1, 0.01), 2000, "strip", 0)
        ens.classify_with(threshold_rule=rule)
        mu[rule] = ens.run(3000).diffusion().mu
    assert whole["mu"] == resumed["mu"] == mu["positive"] != mu["strict"]
