"""What every subcommand shares: the one-line error, JSON output, flags built from RunSpec.

A setting of a run has one name: the flag of a :class:`~warpratchet.spec.RunSpec` field is the
field's name with dashes (``chunk_steps`` -> ``--chunk-steps``), and its type, range, choices,
default and help come from the field (:func:`spec_flag`); a subcommand states only where its
meaning differs (e.g. ``sumrule``'s default of 30000 steps). Bad values fail while parsing, with
the flag named: ``argument --points: points = 0 is outside the allowed range 1 <= points``.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import difflib
import json
import math
import sys
from collections.abc import Callable, Iterable, Iterator
from typing import Any, NoReturn

from ..errors import ParameterError, Terminated, check_count
from ..progress import ProgressBar
from ..runloop import deferred_interrupts
from ..spec import RENAMED, RunSpec, setting_of

__all__ = [
    "UsageError",
    "Interrupted",
    "stopping",
    "Parser",
    "ProgressBar",
    "emit_json",
    "count_type",
    "positive_int",
    "nonnegative_int",
    "flag_name",
    "spec_flag",
    "spec_flags",
    "spec_from_args",
    "add_long_flag",
    "check_duration",
    "print_warnings",
]

_FROM_SPEC = object()  # "take it from the RunSpec field"


class UsageError(Exception):
    """Bad input from the user: reported as ``<prog>: error: <message>``, exit status 2.

    ``prog`` is the command that refused it (``warpratchet`` or, for argparse's errors, the
    subcommand, as argparse names it); ``hint`` follows the message. ``usage``, if given, is
    printed on the line before: a parse error shows a short usage line (argparse's
    convention), an error found while a command runs is the error line alone.
    """

    def __init__(self, message: str, prog: str = "warpratchet", hint: str = "", usage: str = "") -> None:
        super().__init__(message)
        self.prog = prog
        self.hint = hint
        self.usage = usage


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, with where it stopped, what was kept and how to go on.

    The CLI prints ``warpratchet: interrupted <message>`` (SIGTERM: ``terminated``), e.g.
    ``... interrupted at step 2000 of 120000``, and exits with :attr:`status`: 130 (128 + SIGINT)
    or 143 (128 + SIGTERM).
    """

    def __init__(self, message: str = "", *, terminated: bool = False) -> None:
        super().__init__(message)
        self.terminated = terminated
        self.status = 143 if terminated else 130


@contextlib.contextmanager
def stopping(describe: Callable[[], str]) -> Iterator[None]:
    """Run the block with Ctrl-C and SIGTERM deferred to its end, then raise :class:`Interrupted`.

    What the block closes (an archive, after the run wrote its checkpoint where it stopped)
    closes before the signal is acted on, so a second Ctrl-C cannot cut it short; the signal
    then becomes one :class:`Interrupted` whose message is ``describe()``.
    """
    try:
        with deferred_interrupts():
            yield
    except (KeyboardInterrupt, Terminated) as exc:
        raise Interrupted(describe(), terminated=isinstance(exc, Terminated)) from None


#: Longest usage line printed as argparse writes it; a longer usage is shortened to one line.
_USAGE_WIDTH = 100


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are argparse's two lines, kept short: a one-line usage and
    ``<prog>: error: <message>`` naming the value and its range (:meth:`short_usage`)."""

    def short_usage(self) -> str:
        """argparse's usage if it is one short line, else one that says where the options are:
        ``usage: <prog> [options]  (<prog> --help lists them)``."""
        usage = self.format_usage().strip()
        if "\n" not in usage and len(usage) <= _USAGE_WIDTH:
            return usage
        return f"usage: {self.prog} [options]  ({self.prog} --help lists them)"

    def error(self, message: str) -> NoReturn:
        raise UsageError(message, prog=self.prog, hint=self._suggestion(message), usage=self.short_usage())

    def parse_known_args(self, args=None, namespace=None):
        # Kept for the error's hint: argparse reports a missing required flag before an unknown one.
        self._words = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def _suggestion(self, message: str) -> str:
        """``; did you mean --k -> --K?`` for an unknown flag close to one this parser has (the same
        letters in another case first, then :func:`difflib.get_close_matches`), after an
        unrecognized argument or a missing required one."""
        if not message.startswith(("unrecognized arguments:", "the following arguments are required")):
            return ""
        words = getattr(self, "_words", [])
        parsers = [self]  # the top level reports a subcommand's unknown flags: look in it too
        for action in self._subparsers._group_actions if self._subparsers else ():
            parsers += [action.choices[w] for w in words[:1] if w in action.choices]
        flags = {flag for p in parsers for flag in p._option_string_actions}
        known = sorted(flag for flag in flags if flag.startswith("--"))
        unknown = message.removeprefix("unrecognized arguments:").split() if message[0] == "u" else words
        hints = []
        for word in unknown:
            flag = word.split("=", 1)[0]
            if not flag.startswith("--") or flag in flags:
                continue
            same = [k for k in known if k.lower() == flag.lower()]
            close = same or difflib.get_close_matches(flag, known, n=1, cutoff=0.75)
            if close:
                hints.append(f"{flag} -> {close[0]}")
        return f"; did you mean {', '.join(hints)}?" if hints else ""


def _clean(value: Any) -> Any:
    """JSON-safe: NaN and infinities become null, NumPy scalars become Python numbers."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def emit_json(obj: dict[str, Any]) -> None:
    """Print one JSON object on stdout (NaN as null)."""
    print(json.dumps(_clean(obj), allow_nan=False))


_KIND_NAMES = {int: "integer", float: "float", str: "string"}


def _integer(text: str) -> int:
    """A count from the command line: ``100000``, or an integral value in scientific notation
    (``1e5``, ``2.5e6``); ``1.5`` or ``1e-3`` is a ValueError (a count is a whole number)."""
    try:
        return int(text)
    except ValueError:
        pass
    value = float(text)  # a ValueError for text that is no number at all
    if not (math.isfinite(value) and value.is_integer() and abs(value) < 2.0**63):
        raise ValueError(f"{text!r} is not a whole number")
    return int(value)


def _typed(kind: type, check, message: str | None = None) -> Any:
    """An argparse type: ``kind(text)``, then ``check(value)``.

    A refused value's message is the validator's (it names the value and range), or
    ``message.format(value=value)`` where a command line keeps an older wording.
    """

    def parse(text: str):
        try:
            value = _integer(text) if kind is int else kind(text)
        except ValueError:
            whole = " (a whole number: 100000 or 1e5)" if kind is int else ""
            raise argparse.ArgumentTypeError(f"invalid {_KIND_NAMES[kind]} value: {text!r}{whole}") from None
        try:
            return check(value)
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(
                str(exc) if message is None else message.format(value=value)
            ) from None

    parse.__name__ = _KIND_NAMES[kind]
    return parse


def count_type(name: str, low: int, high: int | None = None) -> Any:
    """argparse type: an integer in ``[low, high]`` (:func:`warpratchet.errors.check_count`)."""
    return _typed(int, lambda value: check_count(name, value, low, high))


#: argparse types for unnamed counts (the benchmarks' command lines; argparse names the flag).
positive_int = _typed(
    int, lambda value: check_count("N", value, 1), "{value} is outside the allowed range >= 1"
)
nonnegative_int = _typed(
    int, lambda value: check_count("N", value, 0), "{value} is outside the allowed range >= 0"
)


def flag_name(name: str) -> str:
    """The CLI flag of a setting: its name with dashes (``chunk_steps`` -> ``--chunk-steps``)."""
    return "--" + name.replace("_", "-")


def spec_flag(
    parser: Any,
    name: str,
    *,
    default: Any = _FROM_SPEC,
    help: str | None = None,
    required: bool | None = None,
) -> None:
    """Add the flag of RunSpec setting ``name`` to ``parser`` (or an argument group).

    Type, range and choices always come from the setting; ``default`` and ``help`` do too unless
    a subcommand gives its own (its meaning differs there). A setting without a default is a
    required flag unless ``default`` is given.
    """
    field_default, setting = setting_of(name)
    if default is _FROM_SPEC:
        default = None if field_default is dataclasses.MISSING else field_default
        if required is None:
            required = field_default is dataclasses.MISSING
    text = setting.help if help is None else help
    if help is None and default is not None:
        text += f" (default {default})"
    kwargs: dict[str, Any] = {"default": default, "required": bool(required), "help": text}
    if setting.choices is not None:
        kwargs["choices"] = list(setting.choices)
    else:
        kwargs["type"] = _typed(setting.kind, lambda value: setting.validate(name, value))
    parser.add_argument(flag_name(name), dest=name, **kwargs)
    for old in (old for old, new in RENAMED.items() if new == name):
        kwargs = {**kwargs, "default": argparse.SUPPRESS, "required": False, "help": argparse.SUPPRESS}
        parser.add_argument(flag_name(old), dest=name, action=_FormerFlag, now=flag_name(name), **kwargs)


class _FormerFlag(argparse.Action):
    """The former spelling of a setting's flag (:data:`~warpratchet.spec.RENAMED`), left out of
    ``--help``: it sets the setting and says on stderr what the flag is called now."""

    def __init__(self, *args: Any, now: str, **kwargs: Any) -> None:
        self.now = now
        super().__init__(*args, **kwargs)

    def __call__(self, parser: Any, namespace: argparse.Namespace, values: Any, option_string: Any = None):
        print(f"warpratchet: warning: {option_string} is spelled {self.now}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def spec_flags(parser: Any, names: Iterable[str], **overrides: dict[str, Any]) -> None:
    """:func:`spec_flag` for each name; ``overrides[name]`` holds that flag's own keywords."""
    for name in names:
        spec_flag(parser, name, **overrides.get(name, {}))


def spec_from_args(args: argparse.Namespace, cls: type = RunSpec, **fixed: Any) -> Any:
    """The spec (``RunSpec`` or ``SweepSpec``) of the parsed flags; ``None`` flags take the default."""
    names = [f.name for f in dataclasses.fields(cls)]
    values = {n: getattr(args, n) for n in names if getattr(args, n, None) is not None}
    return cls.from_dict({**values, **fixed})


def print_warnings(caught: Iterable[Any]) -> None:
    """Warnings caught while reading a file, one line each on stderr."""
    for w in caught:
        print(f"warpratchet: warning: {w.message}", file=sys.stderr)


#: Upper bounds of the kernels' speed in point-steps per second (about 8x what a CPU thread and
#: 10x what a large GPU reach): an estimate at these speeds is a lower bound of the run time.
FASTEST_CPU_THREAD, FASTEST_GPU = 1e10, 1e12
#: Estimated seconds (at the fastest speeds) above which ``--long`` is required: a day.
LONG_SECONDS = 86400.0
#: What a refused archive write tells a CLI user to do once there is space.
HOW_TO_CONTINUE = "run the same command again to resume it"


def add_long_flag(parser: Any) -> None:
    """``--long``: let through a request :func:`check_duration` refuses."""
    parser.add_argument(
        "--long",
        action="store_true",
        help=f"run a request estimated to take over {LONG_SECONDS / 3600:.0f} h even at the kernels' "
        "fastest speed",
    )


def check_duration(
    args: argparse.Namespace, what: str, point_steps: int, threads: int | None, device: str | None
) -> None:
    """UsageError with the estimate for a request that cannot end within a day (unless ``--long``).

    ``point_steps`` (``what``, e.g. ``"10 points x 2000 steps"``) at :data:`FASTEST_CPU_THREAD`
    per thread, or :data:`FASTEST_GPU` on a GPU ``device``: a lower bound of the time it takes.
    """
    from ..runloop import default_threads

    if args.long:
        return
    on_gpu = device is not None and not str(device).startswith("cpu")
    speed = FASTEST_GPU if on_gpu else FASTEST_CPU_THREAD * (threads or default_threads())
    seconds = point_steps / speed
    if seconds > LONG_SECONDS:
        days = seconds / 86400
        when = f"{days:.3g} days" if days < 3650 else f"{days / 365.25:.3g} years"
        raise UsageError(
            f"{what} would take at least {when} (at {speed:.3g} point-steps/s, faster than the "
            "kernels run); pass --long to run it"
        )
