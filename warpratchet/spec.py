"""RunSpec: everything that defines a run, each setting's default, range and help text in one place.

A run of warpratchet is the map (K, b1, b2 of Eqs. cpem and fx), an initial ensemble (``init``
sampler, ``points``, ``seed``), a number of iterations (``steps``), the chaos indicator and its
threshold, and how the work is carried out (``threads``, ``device``, ``chunk_steps``, which never
change a result: the ensemble is bitwise independent of them). :class:`RunSpec` holds exactly
that; :class:`SweepSpec` is the subset a sweep shares between its points.

One name per concept. A setting has one name everywhere: the field of :class:`RunSpec`, the CLI
flag (the name with dashes: ``chunk_steps`` -> ``--chunk-steps``), the HDF5 attribute, the sweep
column and the docs. Files written before this module named the sampler ``sampler`` and stored
the default threshold as NaN; :meth:`RunSpec.from_attrs` still reads them (:data:`LEGACY_NAMES`).

"Default" is ``None``: a setting whose default depends on the run (``threads``: one per core;
``chunk_steps``: about 1e9 point-steps; ``threshold``: the indicator's own, for the FTLE
:func:`warpratchet.observables.default_lyapunov_threshold` of ``steps``) is ``None`` in the API,
``null`` in JSON and an absent attribute in HDF5.

Pure: no Warp, no I/O (the CLI builds its parsers from this module without loading Warp).
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from .errors import ParameterError, check_choice, check_count, check_real, renamed_globals, renamed_keyword
from .force import Force, numbers_text, parse_numbers
from .limits import MAX_POINTS, MAX_STEP, check_kernel_range
from .params import MapParams

__all__ = [
    "SAMPLERS",
    "INDICATORS",
    "THRESHOLD_RULES",
    "MAX_THREADS",
    "MAX_CHUNK_STEPS",
    "CHECKPOINT_SECONDS",
    "MAX_CHECKPOINT_SECONDS",
    "LEGACY_NAMES",
    "RENAMED",
    "Setting",
    "RunSpec",
    "SweepSpec",
    "setting_of",
    "check_setting",
    "check_checkpoint_seconds",
    "attr_value",
]

#: Initial-condition samplers: the strip B of Eq. (B) (the paper's ensemble), the torus, a grid.
SAMPLERS = ("strip", "torus", "grid")
#: Chaos indicators: finite-time Lyapunov exponent, MEGNO, fast Lyapunov indicator (sumrule).
INDICATORS = ("ftle", "megno", "fli")
#: How the FTLE threshold depends on n when no ``threshold`` is given: ``strict`` = 10 (1 + ln n)/n
#: (the default), ``positive`` = (1 + ln n)/n (the paper's Fig. 9 ensemble with ``init="torus"``).
#: The factors are :data:`warpratchet.observables.THRESHOLD_RULES`.
THRESHOLD_RULES = ("strict", "positive")
#: Upper bound of ``threads``. Each thread is a Python thread with its own shard and stack; more
#: threads than cores buy nothing, and an unbounded count exhausts memory before it fails.
MAX_THREADS = 4096
#: Upper bound of ``chunk_steps``. Launches split longer chunks (a launch counts its steps in a
#: 32-bit int), but a chunk is also the unit of progress, checkpoints and
#: Ctrl-C, and one of more than 2^31 steps is never what a user meant.
MAX_CHUNK_STEPS = 2**31 - 1
#: An archive checkpoints also whenever the next chunk end would come more than this many
#: seconds (wall clock, the run's own work) after its last checkpoint, whatever the chunk length,
#: so that a kill -9 loses at most about a minute (REBOUND's ``interval_walltime`` is the
#: precedent). A checkpoint writes 56 bytes per point and syncs twice: once a minute it costs
#: far below 1% of the kernel time (benchmarks/archive_overhead.py).
CHECKPOINT_SECONDS = 60.0
#: Largest ``checkpoint_seconds``: a week; a longer interval is a typo, not a schedule.
MAX_CHECKPOINT_SECONDS = 7 * 86400.0
#: Counts are stored as int64 (HDF5 attributes, sweep columns).
_INT64_MAX = 2**63 - 1
#: Former setting names -> their names now: RunSpec's keyword and the CLI flag still take the
#: former one, with a DeprecationWarning.
RENAMED = {"classifier": "indicator"}
#: Old attribute names -> RunSpec names (archive format v1 wrote ``sampler``; archives written
#: before the indicator had its one name store ``classifier``).
LEGACY_NAMES = {"sampler": "init", **RENAMED}
#: ``spec.CLASSIFIERS``, the former name of :data:`INDICATORS`, still works (DeprecationWarning).
__getattr__ = renamed_globals(__name__, {"CLASSIFIERS": "INDICATORS"}, globals())


def check_checkpoint_seconds(value: object) -> float:
    """``checkpoint_seconds`` as a float in ``0 < checkpoint_seconds <= MAX_CHECKPOINT_SECONDS``."""
    return check_real("checkpoint_seconds", value, 0.0, MAX_CHECKPOINT_SECONDS, low_open=True)


def _check_device(name: str, value: object) -> str:
    # Only the form is checked here (this module loads no Warp); Ensemble checks availability.
    if not isinstance(value, str) or not value.strip() or value != value.strip():
        raise ParameterError(f"{name} = {value!r} is not a Warp device name such as 'cpu' or 'cuda:0'")
    return value


def _real(name: str, value: object) -> float:
    # K, b1, b2: finite reals here; their ranges are MapParams' (checked together in __post_init__).
    return check_real(name, value)


def _numbers(name: str, value: object) -> str:
    # knots, values: exact numbers, stored as their exact text (their joint checks are Force's).
    return numbers_text(parse_numbers(name, value))


def _count(low: int, high: int) -> Callable[[str, object], int]:
    def check(name: str, value: object) -> int:
        return check_count(name, value, low, high)

    return check


def _threshold(name: str, value: object) -> float:
    return check_real(name, value, 0.0)


@dataclass(frozen=True)
class Setting:
    """What the code knows about one setting besides its default.

    Attributes
    ----------
    help : str
        One line for ``--help`` and the docs (the default is appended by the CLI).
    kind : type
        ``int``, ``float`` or ``str``: how the CLI reads the flag's text.
    check : callable, optional
        ``check(name, value) -> value``: the validated value as a plain Python type, or
        :class:`~warpratchet.errors.ParameterError` naming the value and the allowed range.
    choices : tuple of str, optional
        The allowed values of a string setting (then ``check`` is
        :func:`~warpratchet.errors.check_choice`).
    optional : bool
        ``None`` is allowed and means "the default that depends on the run" (see ``help``).
    """

    help: str
    kind: type
    check: Callable[[str, object], Any] | None = None
    choices: tuple[str, ...] | None = None
    optional: bool = False

    def validate(self, name: str, value: object) -> Any:
        """``value`` checked as setting ``name`` (``None`` passes for an optional setting)."""
        if value is None and self.optional:
            return None
        if self.choices is not None:
            return check_choice(name, value, self.choices)
        return self.check(name, value)


_REQUIRED = dataclasses.MISSING
#: name -> (default, Setting): the one table of every setting of a run.
_SETTINGS: dict[str, tuple[Any, Setting]] = {
    "K": (_REQUIRED, Setting("kick strength, 0 < K < 4 (Eq. cpem)", float, _real)),
    "b1": (
        None,
        Setting("left strip width, b1 > 0 (Eq. fx; or --knots, --values)", float, _real, optional=True),
    ),
    "b2": (
        None,
        Setting(
            "right strip width, b2 > 0, b1 + b2 < 1 (Eq. fx; or --knots, --values)",
            float,
            _real,
            optional=True,
        ),
    ),
    "knots": (
        None,
        Setting(
            "another piecewise-linear force instead of b1, b2: its knots 0 = x_0 < ... < x_{n-1} < 1, "
            "comma-separated (with --values)",
            str,
            _numbers,
            optional=True,
        ),
    ),
    "values": (
        None,
        Setting(
            "the force at --knots, comma-separated; linear in between, f(1) = f(0), mean 0",
            str,
            _numbers,
            optional=True,
        ),
    ),
    "init": (
        "strip",
        Setting("initial conditions: the strip B of Eq. (B), the torus, or a grid", str, choices=SAMPLERS),
    ),
    "points": (10_000, Setting("ensemble size", int, _count(1, MAX_POINTS))),
    "seed": (0, Setting("NumPy seed of the sampler", int, _count(0, _INT64_MAX))),
    "steps": (120_000, Setting("iterations n", int, _count(1, MAX_STEP))),
    "indicator": ("ftle", Setting("chaos indicator", str, choices=INDICATORS)),
    "threshold": (
        None,
        Setting(
            "indicator value above which a point counts as chaotic, >= 0 "
            "(default: the indicator's own; for the FTLE, that of --threshold-rule)",
            float,
            _threshold,
            optional=True,
        ),
    ),
    "threshold_rule": (
        "strict",
        Setting(
            "FTLE threshold when --threshold is not given: strict = 10 (1 + ln n)/n, positive = "
            "(1 + ln n)/n (the paper's Fig. 9 ensemble, with --init torus)",
            str,
            choices=THRESHOLD_RULES,
        ),
    ),
    "threads": (
        None,
        Setting(
            f"CPU threads, 1 to {MAX_THREADS} (default: one per core)",
            int,
            _count(1, MAX_THREADS),
            optional=True,
        ),
    ),
    "device": ("cpu", Setting("Warp device, e.g. cpu or cuda:0", str, _check_device)),
    "chunk_steps": (
        None,
        Setting(
            "steps between observer calls (default: ~1e9 point-steps; with --out, the "
            "archive's, long enough that its rows cost under 0.5 percent of the run)",
            int,
            _count(1, MAX_CHUNK_STEPS),
            optional=True,
        ),
    ),
}


def _field(name: str) -> Any:
    """The dataclass field of setting ``name``: its default and its :class:`Setting` as metadata."""
    default, setting = _SETTINGS[name]
    return dataclasses.field(default=default, metadata={"setting": setting})


def setting_of(name: str) -> tuple[Any, Setting]:
    """``(default, Setting)`` of a setting (the default is ``dataclasses.MISSING`` if required)."""
    try:
        return _SETTINGS[name]
    except KeyError:
        raise ParameterError(f"{name!r} is not a setting of a run (known: {', '.join(_SETTINGS)})") from None


def check_setting(name: str, value: object) -> Any:
    """``value`` validated as setting ``name`` (``None`` passes for an optional one)."""
    return setting_of(name)[1].validate(name, value)


class _Spec:
    """Validation, dict/JSON and HDF5-attribute round trips shared by RunSpec and SweepSpec."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, check_setting(f.name, getattr(self, f.name)))
        rule = getattr(self, "threshold_rule", "strict")
        if getattr(self, "threshold", None) is not None and rule != "strict":
            raise ParameterError(
                f"threshold = {self.threshold!r} and threshold_rule = {rule!r} both given; a threshold "
                "replaces the rule (give one of them)"
            )

    def as_dict(self) -> dict[str, Any]:
        """Every setting as a plain Python value (``None`` for a run-dependent default)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def to_json(self) -> str:
        """One JSON object (``null`` for a run-dependent default)."""
        return json.dumps(self.as_dict())

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]):
        """The spec of a mapping of setting names; unknown names are an error, missing ones default."""
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise ParameterError(
                f"{unknown[0]!r} is not a setting of {cls.__name__} (known: {', '.join(names)})"
            )
        missing = [f.name for f in dataclasses.fields(cls) if f.default is _REQUIRED and f.name not in values]
        if missing:
            raise ParameterError(f"{cls.__name__} needs {', '.join(missing)}")
        return cls(**values)

    @classmethod
    def from_json(cls, text: str | bytes):
        """The spec of :meth:`to_json`'s output."""
        try:
            values = json.loads(text)
        except ValueError as exc:
            raise ParameterError(f"not a JSON {cls.__name__}: {exc}") from None
        if not isinstance(values, dict):
            raise ParameterError(f"a JSON {cls.__name__} is an object; got {type(values).__name__}")
        return cls.from_dict(values)

    def to_attrs(self) -> dict[str, int | float | str]:
        """HDF5-attribute-safe values (int, float, str); a ``None`` setting is left out."""
        return {name: value for name, value in self.as_dict().items() if value is not None}

    @classmethod
    def from_attrs(cls, attrs: Mapping[str, Any]):
        """The spec stored as HDF5 attributes (e.g. ``h5py`` ``obj.attrs``).

        Attributes that are not settings (a file's format, version, ...) are ignored; an absent
        setting takes its default. Files of format v1 are read too: ``sampler`` is ``init`` and
        a NaN ``threshold`` is the default (``None``).
        """
        names = {f.name for f in dataclasses.fields(cls)}
        values = {}
        for key, raw in attrs.items():
            name = LEGACY_NAMES.get(key, key)
            if name in names:
                values[name] = attr_value(raw)
        if isinstance(values.get("threshold"), float) and math.isnan(values["threshold"]):
            values["threshold"] = None
        return cls.from_dict(values)


def attr_value(value: Any) -> Any:
    """A Python value from an HDF5 attribute: bytes -> str, NumPy scalars and 0-d arrays -> scalars.

    The one decoder of stored attributes (run settings, archive and sweep metadata)."""
    if isinstance(value, bytes):
        return value.decode()
    if hasattr(value, "shape") and getattr(value, "shape", None) == ():
        value = value[()]
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return float(value)
    return value


@dataclass(frozen=True)
class RunSpec(_Spec):
    """Everything that defines a run: the map, the ensemble, the iterations, the indicator, the executor.

    Every field is validated once, here (NumPy integers and reals are accepted and stored as
    plain Python values; bool, NaN and out-of-range values raise
    :class:`~warpratchet.errors.ParameterError`, a ``ValueError``, naming the value and range).

    Parameters
    ----------
    K, b1, b2 : float
        The map (Eqs. cpem, fx): ``0 < K < 4``, ``b1, b2 > 0``, ``b1 + b2 < 1``; see :attr:`params`.
        ``b1`` and ``b2`` must also be wide enough for the kernels' float64 tangent (about
        ``>= 1.4e-26`` at K = 3: :func:`warpratchet.limits.check_kernel_range`).
    init : str
        Sampler of the initial ensemble, one of :data:`SAMPLERS` (default ``"strip"``, Eq. B).
    points : int
        Ensemble size, ``1..MAX_POINTS`` (default 10^4, the paper's); whether this machine has
        the memory is checked where the ensemble is built (:func:`warpratchet.limits.check_memory`).
    seed : int
        NumPy seed of the sampler, ``>= 0`` (default 0).
    steps : int
        Iterations ``n`` (the total a run reaches), ``>= 1`` (default 120000, the paper's).
    indicator : str
        Chaos indicator, one of :data:`INDICATORS` (default ``"ftle"``; ``megno``/``fli`` are
        used by the sum-rule census). ``classifier=`` is its former spelling (a
        :class:`DeprecationWarning`).
    threshold : float or None
        Indicator value above which a point counts as chaotic, ``>= 0``; ``None``: the
        indicator's default (for the FTLE, per iteration, the rule ``threshold_rule``).
    threshold_rule : str
        The FTLE threshold when ``threshold`` is None, one of :data:`THRESHOLD_RULES`:
        ``"strict"`` (default) ``10 (1 + ln n)/n``, ``"positive"`` ``(1 + ln n)/n``
        (:func:`warpratchet.observables.lyapunov_threshold`). Not both with a ``threshold``.
    threads : int or None
        CPU threads, ``1..MAX_THREADS``; ``None``: one per core. Results do not depend on it.
    device : str
        Warp device (``"cpu"``, ``"cuda:0"``, ...).
    chunk_steps : int or None
        Steps between observer calls, ``1..MAX_CHUNK_STEPS``; ``None``: about 1e9
        point-steps. Results do not depend on it.
    knots, values : str or None
        Another force instead of ``b1, b2`` (:meth:`warpratchet.force.Force.from_knots`): its
        knots ``0 = x_0 < ... < x_{n-1} < 1`` and values, comma-separated exact numbers, stored
        as their exact text; the mean must be exactly zero and ``max |K f| < 2``.

    Examples
    --------
    >>> spec = RunSpec(K=3, b1=0.1, b2=0.01)
    >>> RunSpec.from_json(spec.to_json()) == spec
    True
    """

    K: float = _field("K")
    b1: float | None = _field("b1")
    b2: float | None = _field("b2")
    init: str = _field("init")
    points: int = _field("points")
    seed: int = _field("seed")
    steps: int = _field("steps")
    indicator: str = _field("indicator")
    threshold: float | None = _field("threshold")
    threshold_rule: str = _field("threshold_rule")
    threads: int | None = _field("threads")
    device: str = _field("device")
    chunk_steps: int | None = _field("chunk_steps")
    knots: str | None = _field("knots")
    values: str | None = _field("values")

    def __post_init__(self) -> None:
        super().__post_init__()
        # The map's ranges are MapParams' and Force's (one definition); a run also needs the
        # kernels to carry its arithmetic (limits.check_kernel_range).
        check_kernel_range(self.params)

    @property
    def params(self) -> MapParams:
        """The map of this run: the paper's ``b1, b2`` or the force of ``knots, values``."""
        return params_of(self.K, self.b1, self.b2, self.knots, self.values)


# RunSpec(classifier=...), the former keyword (spec.RENAMED), still works with a DeprecationWarning.
RunSpec.__init__ = renamed_keyword("classifier", "indicator")(RunSpec.__init__)


def params_of(K, b1=None, b2=None, knots=None, values=None) -> MapParams:
    """The map of ``K`` with the paper's ``b1, b2`` or another force's ``knots, values``.

    Raises
    ------
    ParameterError
        If neither pair, both, or half of one is given, or if a value is outside its range.
    """
    paper, table = (b1, b2) != (None, None), (knots, values) != (None, None)
    if paper and table:
        raise ParameterError("b1, b2 and knots, values give two forces; give one pair")
    if table:
        if knots is None or values is None:
            raise ParameterError(
                f"{'values' if values is None else 'knots'} is missing: knots and values go together"
            )
        return MapParams(K, table=Force.from_knots(knots, values))
    if b1 is None or b2 is None:
        raise ParameterError(
            f"{'b1' if b1 is None else 'b2'} is missing: give b1 and b2 (or knots and values)"
        )
    return MapParams(K, b1, b2)


@dataclass(frozen=True)
class SweepSpec(_Spec):
    """The ensemble run at every point of a sweep: the subset of :class:`RunSpec` points share.

    The fields are RunSpec's (same names, defaults, ranges): ``points``, ``steps``, ``init``,
    ``seed`` (the root seed: point ``i`` uses :func:`warpratchet.sweep.point_seed`
    ``(seed, i)``), ``threshold`` and ``threshold_rule`` (a sweep file written before the rule
    existed stores none: it is the default, ``"strict"``). The map varies from point to point,
    and threads never change a row, so neither is part of a sweep's identity (a sweep file
    stores this spec and resumes only the same one).
    """

    points: int = _field("points")
    steps: int = _field("steps")
    init: str = _field("init")
    seed: int = _field("seed")
    threshold: float | None = _field("threshold")
    threshold_rule: str = _field("threshold_rule")

    def at(self, params: MapParams, seed: int, threads: int | None = None) -> RunSpec:
        """The :class:`RunSpec` of one point: this spec at ``params`` with the point's own ``seed``."""
        # Every field of this spec is a RunSpec field of the same name (one name per concept).
        return RunSpec(**params.as_dict(derived=False), **{**self.as_dict(), "seed": seed}, threads=threads)
