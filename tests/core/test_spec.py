"""RunSpec: one definition of every setting, validated once, JSON and HDF5-attribute round trips."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from warpratchet import RunSpec
from warpratchet.cli import build_parser
from warpratchet.errors import ParameterError
from warpratchet.limits import MAX_POINTS
from warpratchet.params import MapParams
from warpratchet.spec import INDICATORS, MAX_CHUNK_STEPS, MAX_THREADS, SAMPLERS, SweepSpec

DATA = Path(__file__).parent.parent / "data"


def test_the_acceptance_spec_round_trips_through_json():
    spec = RunSpec(K=3, b1=0.1, b2=0.01)
    assert RunSpec.from_json(spec.to_json()) == spec
    assert spec.params == MapParams(3.0, 0.1, 0.01)
    assert type(spec.K) is float and spec.threshold is None and spec.init == "strip"
    assert json.loads(spec.to_json())["threshold"] is None  # "default" is null in JSON


def _attrs_round_trip(spec: RunSpec) -> RunSpec:
    """Through real HDF5 attributes (an in-memory file), as an archive would store them."""
    with h5py.File("spec.h5", "w", driver="core", backing_store=False) as f:
        f.attrs.update(spec.to_attrs())
        return RunSpec.from_attrs(f.attrs)


_valid_specs = st.builds(
    RunSpec,
    K=st.floats(0.0, 4.0, exclude_min=True, exclude_max=True),
    b1=st.floats(1e-9, 0.49),
    b2=st.floats(1e-9, 0.49),
    init=st.sampled_from(SAMPLERS),
    points=st.integers(1, MAX_POINTS),
    seed=st.integers(0, 2**63 - 1),
    steps=st.integers(1, 2**63 - 1),
    indicator=st.sampled_from(INDICATORS),
    threshold=st.none() | st.floats(0.0, 1e300),
    threads=st.none() | st.integers(1, MAX_THREADS),
    device=st.sampled_from(["cpu", "cuda:0"]),
    chunk_steps=st.none() | st.integers(1, MAX_CHUNK_STEPS),
)


@given(_valid_specs)
def test_every_valid_spec_round_trips_through_json_and_hdf5_attributes(spec):
    assert RunSpec.from_json(spec.to_json()) == spec
    assert _attrs_round_trip(spec) == spec
    assert all(value is not None for value in spec.to_attrs().values())


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"points": 0}, r"^points = 0 is outside the allowed range 1 <= points"),
        ({"points": True}, "points = True is not an integer"),
        ({"steps": 1.5}, "steps = 1.5 is not an integer"),
        ({"seed": -1}, "seed = -1 is outside"),
        ({"threshold": math.nan}, "threshold = nan is not finite"),
        ({"threshold": -1.0}, r"threshold = -1.0 is outside the allowed range 0.0 <= threshold"),
        ({"threads": MAX_THREADS + 1}, f"threads = {MAX_THREADS + 1} is outside"),
        ({"chunk_steps": 2**31}, "chunk_steps = 2147483648 is outside"),
        ({"init": "disk"}, "init = 'disk' is not one of strip, torus, grid"),
        ({"indicator": "gali"}, "indicator = 'gali'"),
        ({"device": ""}, "device = ''"),
        ({"K": 4.0}, "K = 4.0 is outside the allowed range 0 < K < 4"),
        ({"b1": 0.6, "b2": 0.5}, r"b1 \+ b2 = 1.1 is outside the allowed range b1 \+ b2 < 1"),
    ],
)
def test_bad_values_are_refused_in_one_line_naming_value_and_range(changes, message):
    with pytest.raises(ParameterError, match=message) as err:
        RunSpec(**{"K": 3.0, "b1": 0.1, "b2": 0.01, **changes})
    assert "\n" not in str(err.value)


def test_numpy_scalars_are_accepted_and_stored_as_python_values():
    spec = RunSpec(
        K=np.float32(3.0), b1=0.1, b2=0.01, points=np.int64(100), seed=np.uint32(7), steps=np.int32(10),
        threshold=np.float32(0.5), threads=np.int64(2), chunk_steps=np.int16(4),
    )  # fmt: skip
    for name in ("points", "seed", "steps", "threads", "chunk_steps"):
        assert type(getattr(spec, name)) is int
    assert type(spec.threshold) is float and spec.threshold == 0.5
    assert RunSpec.from_json(spec.to_json()) == spec


def test_json_refuses_unknown_and_missing_settings():
    with pytest.raises(ParameterError, match="'sampler' is not a setting of RunSpec"):
        RunSpec.from_json('{"K": 3, "b1": 0.1, "b2": 0.01, "sampler": "strip"}')
    with pytest.raises(ParameterError, match="RunSpec needs K"):
        RunSpec.from_json('{"b1": 0.1, "b2": 0.01}')
    with pytest.raises(ParameterError, match="is an object"):
        RunSpec.from_json("[3, 0.1, 0.01]")


def test_format_v1_archive_attributes_read_as_a_run_spec():
    """archive_v1.h5 names the sampler ``sampler`` and stores the default threshold as NaN."""
    with h5py.File(DATA / "archive_v1.h5", "r") as f:
        spec = RunSpec.from_attrs({**f["params"].attrs, **f["settings"].attrs})
    assert spec == RunSpec(
        K=3.0, b1=0.1, b2=0.01, init="strip", points=200, seed=0, threads=2, chunk_steps=64, threshold=None
    )


def test_sweep_spec_is_the_run_spec_subset_with_the_same_definitions():
    run_fields = {f.name: f for f in dataclasses.fields(RunSpec)}
    for f in dataclasses.fields(SweepSpec):
        assert f.default == run_fields[f.name].default
        assert f.metadata["setting"] is run_fields[f.name].metadata["setting"]
    sweep = SweepSpec(points=np.int64(100), threshold=np.float32(0.5))
    assert SweepSpec.from_json(sweep.to_json()) == sweep
    at = sweep.at(MapParams(3.0, 0.1, 0.01), seed=11, threads=1)
    assert (at.points, at.steps, at.init, at.seed, at.threshold, at.threads) == (
        100,
        120_000,
        "strip",
        11,
        0.5,
        1,
    )


def test_choices_are_the_ones_the_code_implements():
    from warpratchet import ensemble, sumrule

    assert ensemble.SAMPLERS == SAMPLERS
    # sumrule keeps its own tuple until the house branches merge; they must agree.
    assert tuple(sumrule.INDICATORS) == INDICATORS


def test_the_chaos_indicator_is_named_indicator_and_classifier_still_works():
    # One name, indicator, as the sum rule's modules and the kernel; the former spelling keeps
    # working for one release: the keyword, the constant and (archives) the attribute.
    from warpratchet import spec, sumrule

    with pytest.warns(DeprecationWarning, match=r"RunSpec\(classifier=\.\.\.\) is spelled indicator="):
        old = RunSpec(K=3, b1=0.1, b2=0.01, classifier="megno")
    assert old == RunSpec(K=3, b1=0.1, b2=0.01, indicator="megno")
    with pytest.warns(DeprecationWarning, match="spec.CLASSIFIERS is spelled warpratchet.spec.INDICATORS"):
        assert spec.CLASSIFIERS == INDICATORS
    with pytest.warns(DeprecationWarning, match="INDICATORS"):
        assert sumrule.CLASSIFIERS == INDICATORS
    with pytest.warns(DeprecationWarning, match=r"default_threshold\(classifier=\.\.\.\)"):
        assert sumrule.default_threshold(classifier="megno", step=10) == sumrule.MEGNO_THRESHOLD
    assert RunSpec.from_attrs({"K": 3, "b1": 0.1, "b2": 0.01, "classifier": "fli"}).indicator == "fli"


def test_the_former_flag_classifier_still_sets_the_indicator_and_says_its_name(capsys):
    argv = ["sumrule", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "10"]
    assert build_parser().parse_args(argv).indicator == "ftle"
    assert capsys.readouterr().err == ""
    assert build_parser().parse_args([*argv, "--classifier", "megno"]).indicator == "megno"
    assert capsys.readouterr().err == "warpratchet: warning: --classifier is spelled --indicator\n"
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    text = sub.choices["sumrule"].format_help()
    assert "--indicator" in text and "--classifier" not in text  # a hidden alias


def test_run_flags_are_the_spec_fields_with_dashes_and_their_defaults():
    from warpratchet.cli.run import RUN_SETTINGS

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    run = {action.dest: action for action in sub.choices["run"]._actions}
    for f in dataclasses.fields(RunSpec):
        if f.name not in RUN_SETTINGS:
            continue
        action = run[f.name]
        assert action.option_strings == ["--" + f.name.replace("_", "-")]
        assert action.required == (f.default is dataclasses.MISSING)
        if f.default is not dataclasses.MISSING:
            assert action.default == f.default


def test_api_counts_accept_numpy_integers_and_bound_chunks():
    """Issue 13, item 8: NumPy integers were refused; item 1: a 2^31-step chunk ran fewer steps."""
    from warpratchet import Ensemble

    p = MapParams(3.0, 0.1, 0.01)
    ens = Ensemble.sample(p, np.int64(16), "strip", np.int64(3), threads=np.int64(1))
    ref = Ensemble.sample(p, 16, "strip", 3, threads=1)
    ens.run(np.int64(20), chunk_steps=np.int32(7))
    ref.run(20)
    for name, values in ens.state().items():
        np.testing.assert_array_equal(values, ref.state()[name])
    with pytest.raises(ParameterError, match="chunk_steps = 2147483648 is outside"):
        ens.run(1, chunk_steps=2**31)
