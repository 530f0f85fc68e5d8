"""Property-based inputs (issue 13, item 6): any value either runs or is refused in one line.

Every field of :class:`RunSpec` and every flag of ``run``, ``sweep``, ``sumrule``, ``theory``,
``inspect``, ``verify`` and ``resume`` is drawn from hostile strategies: integers (NumPy's, huge,
negative, bool), floats (NaN, infinities, subnormals, tiny b, b1 + b2 near 1, K near 0 and 4),
strings, and files that are missing, folders, not HDF5 or empty. The properties:

* the API raises a ``ValueError`` whose message is one line naming the parameter and its range,
  or accepts the value unchanged (as a plain Python number);
* the CLI (in this process, through :func:`warpratchet.cli.main`) exits 0, or 2 with one error
  line (after a short usage line for a flag refused while parsing), never a traceback;
* never silently different: a run that succeeds reports the steps and points asked for, a finite
  state, and no A without a number or an "unreliable" flag.

Runs stay tiny (<= 64 points, <= 300 steps) so that the file takes well under a minute; valid
values that would only take long (10^18 steps) are checked by validation, never run.
``event()`` counts outcomes: ``pytest --hypothesis-show-statistics`` prints them.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from support import MAP_FLAGS, cli, error_line

from warpratchet import Ensemble, RunSpec, summarize
from warpratchet.cli import main
from warpratchet.ensemble import STATE_FIELDS

#: ``WARPRATCHET_FUZZ_SCALE=10`` draws ten times the examples, new ones each time (an exploratory
#: run, outside CI); unset, the suite draws the same examples every run.
SCALE = float(os.environ.get("WARPRATCHET_FUZZ_SCALE", "1"))


def fast(examples: int) -> settings:
    """``examples`` examples, no deadline (a first Warp launch compiles), the same ones every run."""
    checks = [HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
    return settings(
        max_examples=max(1, round(examples * SCALE)),
        deadline=None,
        suppress_health_check=checks,
        derandomize=SCALE == 1,
        database=None,
    )


# -- values -------------------------------------------------------------------------------------------
NUMPY_INTS = (np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64)
HOSTILE_INTS = st.sampled_from([0, -1, -(2**63), 2**31, 2**63 - 1, 2**63, 2**64, 10**30, True, False])
HOSTILE_FLOATS = st.sampled_from(
    [math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, 2.2e-308, 1e-300, 1e-150, 1e-30, 1.4e-26, 1e-7]
    + [np.nextafter(4.0, 0.0), 4.0, np.nextafter(0.0, 1.0), 1 - 1e-16, 0.5, 1.0, -1.0, 1e308]
)
STRINGS = st.sampled_from(
    ["", " ", "abc", "1e6", "0x10", "nan", "None", "3 ", "٣", "1_000", "-0", "cpu", "cuda:9"]
)


def ints(low: int, high: int) -> st.SearchStrategy:
    """Valid counts (small, so that runs stay fast), as Python or NumPy ints, or hostile values."""
    small = st.integers(low, high)
    numpy = st.builds(
        lambda v, t: t(v), st.integers(max(low, 0), min(high, 127)), st.sampled_from(NUMPY_INTS)
    )
    return st.one_of(small, numpy, HOSTILE_INTS, st.floats(allow_nan=True), STRINGS, st.none())


def reals(low: float, high: float) -> st.SearchStrategy:
    numpy = st.builds(lambda v, t: t(v), st.floats(low, high), st.sampled_from((np.float32, np.float64)))
    return st.one_of(st.floats(low, high), numpy, HOSTILE_FLOATS, st.integers(-5, 5), STRINGS, st.none())


def widths() -> st.SearchStrategy:
    """b1, b2: ordinary, tiny (down to subnormal), or near the b1 + b2 < 1 edge."""
    return st.one_of(st.floats(0.001, 0.45), st.floats(1e-320, 1e-20), st.floats(0.49, 1.0), reals(-1.0, 1.0))


FIELD_STRATEGIES = {
    "K": st.one_of(st.floats(0.1, 3.99), st.floats(0.0, 1e-6), st.floats(3.999999, 4.0), reals(-1, 5)),
    "b1": widths(),
    "b2": widths(),
    "init": st.one_of(st.sampled_from(["strip", "torus", "grid"]), STRINGS, st.none()),
    "points": ints(1, 64),
    "seed": ints(0, 10**6),
    "steps": ints(1, 300),
    "indicator": st.one_of(st.sampled_from(["ftle", "megno", "fli"]), STRINGS),
    "threshold": reals(0.0, 2.0),
    "threads": ints(1, 4),
    "device": st.one_of(st.just("cpu"), STRINGS),
    "chunk_steps": ints(1, 400),
}
_NAMES = "|".join(map(re.escape, ["b1 + b2", *FIELD_STRATEGIES]))
#: A refusal names the parameter first, then the range it must be in (or the choices).
_REFUSAL = re.compile(
    rf"^({_NAMES}) = .*(allowed range|range the kernels can carry|is not one of|Warp device name|is not)"
)


def _one_line_naming_the_parameter(exc: BaseException) -> None:
    text = str(exc)
    assert isinstance(exc, ValueError) and "\n" not in text, repr(exc)
    assert _REFUSAL.match(text), text


# -- the API ------------------------------------------------------------------------------------------
@fast(400)
@given(st.fixed_dictionaries({}, optional=FIELD_STRATEGIES))
def test_run_spec_takes_a_value_unchanged_or_names_it_in_one_line(fields):
    fields = {
        k: v for k, v in fields.items() if v is not None or k in ("threshold", "threads", "chunk_steps")
    }
    fields = {"K": 3.0, "b1": 0.1, "b2": 0.01, **fields}
    try:
        spec = RunSpec(**fields)
    except ValueError as exc:
        _one_line_naming_the_parameter(exc)
        event("refused")
        return
    event("accepted")
    for name, value in fields.items():
        got = getattr(spec, name)
        assert got == value and type(got) in (int, float, str, type(None)), (name, value, got)
    assert RunSpec.from_json(spec.to_json()) == spec


_RUNNABLE = {
    **FIELD_STRATEGIES,
    "steps": st.one_of(st.integers(1, 100), HOSTILE_INTS.filter(lambda v: not isinstance(v, int) or v < 1)),
    "device": st.just("cpu"),
}


_RUN_FIELDS = ("K", "b1", "b2", "points", "seed", "init", "steps", "threads", "chunk_steps", "threshold")


@fast(60)
@given(st.fixed_dictionaries({}, optional={k: _RUNNABLE[k] for k in _RUN_FIELDS}))
def test_an_accepted_spec_runs_to_exactly_what_was_asked(fields):
    fields = {"K": 3.0, "b1": 0.1, "b2": 0.01, **{k: v for k, v in fields.items() if v is not None}}
    try:
        spec = RunSpec(**fields)
        ens = Ensemble.sample(spec.params, spec.points, spec.init, spec.seed, threads=spec.threads)
    except ValueError as exc:
        _one_line_naming_the_parameter(exc)
        event("refused")
        return
    ens.run(spec.steps, chunk_steps=spec.chunk_steps)
    event("ran")
    expected_points = math.isqrt(spec.points) ** 2 if spec.init == "grid" else spec.points
    assert ens.step == spec.steps and ens.points == expected_points
    state = ens.state()
    assert all(np.all(np.isfinite(state[name])) for name in STATE_FIELDS)
    summary = summarize(state, ens.step, spec.threshold)
    assert summary.step == spec.steps and (math.isfinite(summary.A) or not summary.reliable)


# -- the CLI ------------------------------------------------------------------------------------------
def _call(argv: list[str]) -> tuple[int, str, str]:
    """``main(argv)`` in this process; any exception escaping it is a traceback (the test fails)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def _check_refusal(code: int, err: str) -> str:
    """Exit 2 and one error line, after a short usage line of the same command if refused while
    parsing (:func:`support.error_line`), and no traceback: the error line."""
    assert code == 2 and "Traceback" not in err, err
    line = error_line(err)
    assert re.match(r"^warpratchet( \w+)?: error: \S", line), err
    return line


#: Text a flag is given that no flag takes: empty, blanks, words, ``1e6`` for a count, NaN.
BAD_TEXT = st.sampled_from(
    ["", " ", "abc", "1e6", "0x10", "nan", "inf", "-inf", "None", "1.5", "-0.0", "3,5"]
)
BIG_INTS = st.sampled_from([-1, 0, 2**31, 2**63 - 1, 2**63, 2**64, 10**30, -(2**63)])
WILD_FLOATS = HOSTILE_FLOATS


@st.composite
def _argv(draw, flags: dict[str, tuple[st.SearchStrategy, st.SearchStrategy]], defaults: dict[str, str]):
    """``(values, hostile)``: every flag of ``defaults`` and some others, each valid (small, fast), and
    up to two of them given a hostile value (text as a command line carries it)."""
    optional = {k: v[0] for k, v in flags.items() if k not in defaults}
    values = {**defaults, **draw(st.fixed_dictionaries({}, optional=optional))}
    values = {k: draw(flags[k][0]) if k in defaults else v for k, v in values.items()}
    hostile = draw(st.lists(st.sampled_from(sorted(flags)), max_size=2, unique=True))
    for k in hostile:
        values[k] = draw(flags[k][1])
    return {k: str(v) for k, v in values.items()}, hostile


def _names(flag: str) -> tuple[str, ...]:
    """How an error line may name a flag: the flag, its setting's name, the map's joint range."""
    name = flag[2:].replace("-", "_")
    return (flag, f"{name} = ", "b1 + b2") if flag in ("--b1", "--b2") else (flag, f"{name} = ", f"{name} ")


def _refused_naming(code: int, err: str, hostile: list[str], values: dict[str, str], again, defaults) -> None:
    """A one-line refusal; with one hostile flag, the line names it (or the value it was given)
    unless the command is refused without it too (a hostile draw may be valid, and the other
    flags' combination the cause: ``--chunk-steps 5`` with ``--checkpoint-every 1``)."""
    line = _check_refusal(code, err)
    if len(hostile) == 1:
        value = values[hostile[0]]
        if any(n in line for n in _names(hostile[0])) or (value.strip() and value in line):
            return
        without = {k: v for k, v in values.items() if k != hostile[0]}
        if hostile[0] in defaults:
            without[hostile[0]] = defaults[hostile[0]]
        assert again(without) != 0, (hostile, line)  # the hostile flag alone caused an unnamed refusal


def _ran_or_refused(argv, values: dict[str, str], hostile: list[str], defaults: dict[str, str]) -> str | None:
    """Run ``argv(values)`` in this process: its stdout, or None after checking its refusal."""
    code, stdout, err = _call(argv(values))
    if code != 0:
        _refused_naming(code, err, hostile, values, lambda v: _call(argv(v))[0], defaults)
        event("refused")
        return None
    event("ran")
    return stdout


def _args(values: dict[str, str]) -> list[str]:
    return [t for kv in values.items() for t in kv]


RUN_FLAGS = {
    "--K": (st.floats(0.5, 3.9), st.one_of(WILD_FLOATS, BAD_TEXT)),
    "--b1": (st.floats(0.01, 0.4), st.one_of(widths(), BAD_TEXT)),
    "--b2": (st.floats(0.01, 0.4), st.one_of(widths(), BAD_TEXT)),
    "--points": (st.integers(1, 64), st.one_of(BIG_INTS, st.sampled_from([10**10, 2 * 10**9]), BAD_TEXT)),
    "--steps": (
        st.integers(1, 200),
        st.one_of(st.integers(-5, 0), st.sampled_from([2**63, 10**30]), BAD_TEXT),
    ),
    "--seed": (st.integers(0, 10**6), st.one_of(st.sampled_from([-1, 2**63, 10**30]), BAD_TEXT)),
    "--init": (st.sampled_from(["strip", "torus", "grid"]), st.one_of(STRINGS, BAD_TEXT)),
    "--threshold": (st.floats(0.0, 1.0), st.one_of(WILD_FLOATS, BAD_TEXT)),
    "--threads": (st.integers(1, 4), st.one_of(BIG_INTS, BAD_TEXT)),
    "--chunk-steps": (st.integers(5, 400), st.one_of(BIG_INTS, BAD_TEXT)),
    "--device": (st.just("cpu"), st.one_of(STRINGS, BAD_TEXT)),
    "--snapshot-every": (st.integers(0, 100), st.one_of(st.sampled_from([-1, 2**64]), BAD_TEXT)),
    "--snapshot-points": (st.integers(1, 100), st.one_of(st.sampled_from([0, -1, 2**64]), BAD_TEXT)),
    "--checkpoint-every": (st.integers(1, 400), st.one_of(st.sampled_from([0, -1, 2**64]), BAD_TEXT)),
    "--rerun-points": (st.integers(1, 100), st.one_of(st.sampled_from([0, -1, 2**64]), BAD_TEXT)),
    "--rerun-every": (st.integers(1, 100), st.one_of(st.sampled_from([0, -1, 2**64]), BAD_TEXT)),
    "--rerun-max-mb": (st.floats(0.1, 20.0), st.one_of(st.sampled_from([0, -1, 1e7]), WILD_FLOATS, BAD_TEXT)),
    "--rerun-color": (st.sampled_from(["ftle", "class"]), st.one_of(STRINGS, BAD_TEXT)),
}
#: Flags that need another one: given alone they are refused ("--snapshot-every needs --out FILE").
_ARCHIVE_FLAGS = ("--snapshot-every", "--snapshot-points", "--checkpoint-every")
_RERUN_FLAGS = ("--rerun-points", "--rerun-every", "--rerun-max-mb", "--rerun-color")
RUN_DEFAULTS = {"--K": "3", "--b1": "0.1", "--b2": "0.01", "--points": "16", "--steps": "50"}


@fast(100)
@given(drawn=_argv(RUN_FLAGS, RUN_DEFAULTS), out=st.booleans())
def test_run_flags_run_or_are_refused_in_one_line(drawn, out, tmp_path_factory):
    values, hostile = drawn
    out = out or any(k in values for k in _ARCHIVE_FLAGS)  # archive options come with --out

    def argv(values: dict[str, str]) -> list[str]:
        files = ["--out", str(tmp_path_factory.mktemp("run") / "run.h5")] if out else []
        if any(k in values for k in _RERUN_FLAGS):
            files += ["--rerun", str(tmp_path_factory.mktemp("rec") / "run.rrd")]
        return ["run", "--quiet", "--json", *_args(values), *files]

    stdout = _ran_or_refused(argv, values, hostile, RUN_DEFAULTS)
    if stdout is None:
        return
    report = json.loads(stdout)
    steps, points = int(values["--steps"]), int(values["--points"])
    assert report["steps"] == steps
    assert report["points"] == (math.isqrt(points) ** 2 if values.get("--init") == "grid" else points)
    assert report["A"] is not None or report["reliable"] is False
    assert report["lyapunov"] is None or math.isfinite(report["lyapunov"])


SWEEP_FLAGS = {
    "--path": (st.sampled_from(["maximal", "line", "fixed-b1", "k"]), st.one_of(STRINGS, BAD_TEXT)),
    "--b2": (
        st.sampled_from(["0.01", "0.01:0.1:2", "0.02:0.03:3"]),
        st.one_of(
            st.sampled_from(["0:1:1000000000000", "0.01:0.02:0", "1e-150", "0.2:0.1:1", "0.9"]), BAD_TEXT
        ),
    ),
    "--b1": (st.floats(0.01, 0.4), st.one_of(widths(), BAD_TEXT)),
    "--Ks": (
        st.sampled_from(["2.5:3.5:2", "3"]),
        st.one_of(st.sampled_from(["0:4:2", "-1:5:3", "1:2:-1"]), BAD_TEXT),
    ),
    "--a": (st.floats(0.2, 3.0), st.one_of(WILD_FLOATS, BAD_TEXT)),
    "--K": (st.floats(0.5, 3.9), st.one_of(WILD_FLOATS, BAD_TEXT)),
    "--points": (st.integers(1, 32), st.one_of(BIG_INTS, BAD_TEXT)),
    "--steps": (st.integers(1, 100), st.one_of(st.sampled_from([0, -1, 2**63, 10**30]), BAD_TEXT)),
    "--seed": (st.integers(0, 100), st.one_of(st.sampled_from([-1, 2**63]), BAD_TEXT)),
    "--threshold": (st.floats(0.0, 1.0), st.one_of(WILD_FLOATS, BAD_TEXT)),
    "--threads": (st.integers(1, 2), st.one_of(BIG_INTS, BAD_TEXT)),
    "--grid": (
        st.sampled_from(["b1=0.05:0.2:2,b2=0.01:0.1:2", "b1=0.1:0.1:1,b2=0.6:0.9:2"]),
        st.one_of(
            st.sampled_from(["b1=0:1:100000,b2=0:1:100000", "b1=0.1", "b2=0.1:0.2:2,b2=0.1:0.2:2"]), BAD_TEXT
        ),
    ),
    "--domain": (
        st.sampled_from(["LR", "L,R", "none", "R"]),
        st.one_of(st.sampled_from(["XY", ",", "LR,,"]), BAD_TEXT),
    ),
}
#: What each path needs besides the defaults (any other flag is refused: "--a is not used by ...").
_PATH_NEEDS = {
    "maximal": ("--b2",),
    "line": ("--a", "--b2"),
    "fixed-b1": ("--b1", "--b2"),
    "k": ("--Ks", "--b1", "--b2"),
}


SWEEP_DEFAULTS = {"--path": "maximal", "--points": "8", "--steps": "20"}


@fast(60)
@given(drawn=_argv(SWEEP_FLAGS, SWEEP_DEFAULTS), out=st.booleans())
def test_sweep_flags_run_or_are_refused_in_one_line(drawn, out, tmp_path_factory):
    values, hostile = drawn
    if "--grid" in values and "--grid" not in hostile and "--path" not in hostile:
        del values["--path"]  # a grid sweep: its own flags only
        values = {k: v for k, v in values.items() if k not in ("--b1", "--b2", "--a", "--Ks") or k in hostile}
    path = values.get("--path", "grid")
    if "--domain" in values and path != "grid" and "--domain" not in hostile:
        del values["--domain"]
    if "--path" not in hostile and path != "grid":  # mostly the flags the path takes, so sweeps run
        keep = set(_PATH_NEEDS.get(path, ())) | {"--path", "--points", "--steps", "--seed", "--threshold",
                                                 "--threads", "--K", "--domain"} | set(hostile)  # fmt: skip
        if path == "k":
            keep.discard("--K")
        values = {k: v for k, v in values.items() if k in keep}
        for need in _PATH_NEEDS.get(path, ()):
            values.setdefault(need, {"--b2": "0.01" if path == "k" else "0.02:0.03:2", "--a": "1.0",
                                     "--b1": "0.1", "--Ks": "2.9:3.1:2"}[need])  # fmt: skip
        if path == "k" and "--b2" not in hostile:
            values["--b2"] = "0.01"

    def argv(values: dict[str, str]) -> list[str]:
        files = ["--out", str(tmp_path_factory.mktemp("sweep") / "sweep.h5")] if out else []
        return ["sweep", "--quiet", "--json", *_args(values), *files]

    stdout = _ran_or_refused(argv, values, hostile, SWEEP_DEFAULTS)
    if stdout is None:
        return
    rows = json.loads(stdout)["rows"]
    assert rows and [r["index"] for r in rows] == list(range(len(rows)))
    for r in rows:
        assert r["steps"] == int(values["--steps"]) and r["points"] == int(values["--points"])
        assert r["A"] is not None or r["chaotic_points"] == 0


SUMRULE_FLAGS = {
    "--K": (st.floats(0.5, 3.9), st.one_of(WILD_FLOATS, BAD_TEXT)),
    "--b1": (st.floats(0.01, 0.4), st.one_of(widths(), BAD_TEXT)),
    "--b2": (st.floats(0.01, 0.4), st.one_of(widths(), BAD_TEXT)),
    "--points": (st.integers(2, 64), st.one_of(BIG_INTS, BAD_TEXT)),
    "--steps": (st.sampled_from([216, 500]), st.one_of(st.sampled_from([0, 8, -1, 2**63]), BAD_TEXT)),
    "--m-max": (st.integers(1, 3), st.one_of(st.sampled_from([0, -1, 2**63]), BAD_TEXT)),
    "--indicator": (st.sampled_from(["ftle", "megno", "fli"]), st.one_of(STRINGS, BAD_TEXT)),
    "--threshold": (st.floats(0.0, 5.0), st.one_of(WILD_FLOATS, BAD_TEXT)),
    "--seed": (st.integers(0, 100), st.one_of(st.sampled_from([-1, 2**63]), BAD_TEXT)),
    "--threads": (st.integers(1, 2), st.one_of(BIG_INTS, BAD_TEXT)),
    "--grid": (st.integers(2, 8), st.one_of(st.sampled_from([40000, 10**6, 1, 0, -3]), BAD_TEXT)),
}


SUMRULE_DEFAULTS = {"--K": "3", "--b1": "0.1", "--b2": "0.01", "--steps": "216", "--m-max": "3"}


@fast(40)
@given(drawn=_argv(SUMRULE_FLAGS, SUMRULE_DEFAULTS))
def test_sumrule_flags_run_or_are_refused_in_one_line(drawn):
    values, hostile = drawn
    if "--grid" in values and "--points" in values and "--grid" not in hostile:
        del values["--grid"]  # both: refused by argparse; keep that for the hostile case only

    def argv(values: dict[str, str]) -> list[str]:
        points = [] if "--points" in values or "--grid" in values else ["--points", "32"]
        return ["sumrule", "--quiet", "--json", *_args(values), *points]

    stdout = _ran_or_refused(argv, values, hostile, SUMRULE_DEFAULTS)
    if stdout is None:
        return
    result = json.loads(stdout)
    assert result["steps"] == int(values["--steps"]) and 0.0 <= result["S_C"] <= 1.0
    side = int(values["--grid"]) if "--grid" in values else None
    assert result["points"] == (side * side if side else int(values.get("--points", "32")))


MAP_DEFAULTS = {"--K": "3", "--b1": "0.1", "--b2": "0.01"}


@fast(60)
@given(drawn=_argv({k: RUN_FLAGS[k] for k in MAP_DEFAULTS}, MAP_DEFAULTS), as_json=st.booleans())
def test_theory_flags(drawn, as_json):
    values, hostile = drawn

    def argv(values: dict[str, str]) -> list[str]:
        return ["theory", *_args(values)] + (["--json"] if as_json else [])

    stdout = _ran_or_refused(argv, values, hostile, MAP_DEFAULTS)
    if stdout is None:
        return
    if as_json:
        out = json.loads(stdout)
        assert (out["K"], out["b1"], out["b2"]) == tuple(float(values[k]) for k in ("--K", "--b1", "--b2"))


# -- file arguments -----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Every kind of file argument: missing, a folder, not HDF5, empty, HDF5 but foreign, and good ones."""
    import h5py

    root = tmp_path_factory.mktemp("files")
    (root / "folder").mkdir()
    (root / "text.h5").write_text("not an archive\n")
    (root / "empty.h5").write_bytes(b"")
    with h5py.File(root / "foreign.h5", "w") as f:
        f["x"] = np.arange(3)
    assert (
        main(
            ["run", *MAP_FLAGS, "--points", "16", "--steps", "100", "--quiet", "--out", str(root / "run.h5")]
        )
        == 0
    )
    assert main(["sweep", "--path", "maximal", "--b2", "0.01:0.02:2", "--points", "8", "--steps", "20",
                 "--quiet", "--out", str(root / "sweep.h5")]) == 0  # fmt: skip
    names = ["missing.h5", "folder", "text.h5", "empty.h5", "foreign.h5", "run.h5", "sweep.h5", ""]
    return root, names


@fast(60)
@given(
    command=st.sampled_from(["inspect", "verify", "resume"]),
    which=st.one_of(st.integers(0, 7), st.just(5)),  # the good archive more often: resume runs
    # resume's --steps is a total: a valid huge one (2^31, 2^63 - 1) would run, for ever; never drawn
    steps=st.one_of(st.integers(-5, 400), HOSTILE_INTS.filter(lambda v: not 400 < v <= 2**63 - 1), STRINGS),
    as_json=st.booleans(),
    checked=st.fixed_dictionaries(
        {},
        optional={  # resume's guards: must equal the archive's (16 points of the strip, seed 0)
            "--points": st.sampled_from(["16", "17", "0", "x"]),
            "--seed": st.sampled_from(["0", "1", "-1"]),
            "--init": st.sampled_from(["strip", "torus", "disk"]),
            "--K": st.sampled_from(["3", "3.5", "nan"]),
            "--threads": st.sampled_from(["1", "2", "0", "5000"]),
            "--device": st.sampled_from(["cpu", "cuda:7", ""]),
        },
    ),
)
def test_file_commands_report_or_refuse_in_one_line(files, command, which, steps, as_json, checked):
    root, names = files
    path = str(root / names[which]) if names[which] else ""
    argv = [command, path] + (["--json"] if as_json else [])
    if command == "resume":
        argv += ["--steps", str(steps), "--quiet", *_args(checked)]
    before = {name: (root / name).read_bytes() for name in ("run.h5", "sweep.h5")}
    code, stdout, err = _call(argv)
    if code == 0:
        event(f"{command}: ok")
        if command == "resume":
            report = json.loads(stdout) if as_json else None
            assert report is None or report["steps"] == int(steps)
            # put the archive back, so that every example starts from the same file
            (root / "run.h5").write_bytes(before["run.h5"])
        return
    if command == "verify" and code == 1:  # verify's "damaged" (never for these files)
        pytest.fail(f"verify called a good or foreign file damaged: {stdout}")
    _check_refusal(code, err)
    event(f"{command}: refused")


# -- a few through a real process ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [
        ["run", *MAP_FLAGS, "--points", "nan", "--quiet"],
        [
            "run",
            "--K",
            "3",
            "--b1",
            "1e-150",
            "--b2",
            "1e-150",
            "--points",
            "1000",
            "--steps",
            "10000",
            "--quiet",
        ],
        ["sweep", "--path", "maximal", "--b2", "0:1:1000000000000", "--quiet"],
        ["sumrule", *MAP_FLAGS, "--grid", "1000000", "--quiet"],
        ["resume", os.devnull, "--steps", "10"],
    ],
)
def test_in_a_real_process_refusals_are_one_line_and_exit_2(argv):
    done = cli(*argv)
    _check_refusal(done.returncode, done.stderr)
