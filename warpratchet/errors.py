"""The error types of warpratchet and the one set of input validators.

Every public entry point (API and CLI alike) checks its inputs with these functions, so a bad
value gives the same one-line message everywhere: the parameter's name, the value, and the
allowed range, e.g. ``points = 0 is outside the allowed range points >= 1``. The CLI prints that
line and exits with status 2.

Conventions:

* counts accept any integral type, NumPy's included, and reject ``bool`` (``True`` is not a
  count) and floats, even integral ones (``1e6`` steps is almost always a typo for an int);
* reals accept any real type (NumPy's included), reject ``bool``, NaN and infinities, and
  check the range with the bounds' openness stated in the message;
* the returned value is a plain Python ``int`` or ``float``, so nothing downstream sees a NumPy
  scalar (whose arithmetic wraps at 64 bits) or a subclass.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

import functools
import math
import numbers
import operator
import warnings
from collections.abc import Callable, Iterable
from typing import Any

__all__ = [
    "WarpratchetError",
    "ParameterError",
    "FileFormatError",
    "ResourceError",
    "NonFiniteStateError",
    "KernelError",
    "Terminated",
    "check_count",
    "check_real",
    "check_choice",
    "check_optional",
    "renamed_attribute",
    "renamed_globals",
    "renamed_keyword",
]


class WarpratchetError(ValueError):
    """Base of warpratchet's own errors; a ``ValueError`` so callers can catch either."""


class ParameterError(WarpratchetError):
    """A value outside its allowed range (the message names the parameter, value and range)."""


class FileFormatError(WarpratchetError):
    """A file that is not what it should be: wrong format, truncated, corrupted, or another run's."""


class ResourceError(WarpratchetError):
    """A request the machine cannot carry out (memory, disk, counts beyond what the code can carry)."""


class NonFiniteStateError(WarpratchetError, FloatingPointError):
    """A state with NaN or infinite values: never summarised as a number, never stored as a checkpoint.

    Also a ``FloatingPointError`` (what :func:`~warpratchet.observables.summarize` raised before).
    """


class KernelError(WarpratchetError, RuntimeError):
    """A kernel launch whose results the code cannot vouch for, refused rather than returned (e.g.
    the transport hooks' guard saw two CPU threads share their scratch). Not the user's input:
    the CLI exits with status 1. Also a ``RuntimeError``.
    """


class Terminated(SystemExit):
    """SIGTERM (a scheduler stopping the job) during a run, raised once the run stopped cleanly.

    A run turns the signal's default action (death) into this exception at the end of the chunk
    in flight, after every observer ended (an archive wrote its checkpoint there): the
    interpreter unwinds, closes what is open and exits with status 143 (128 + SIGTERM), the
    status a shell reports for a process the signal ended.
    """

    def __init__(self, message: str = "") -> None:
        super().__init__(143)
        self.message = message

    def __str__(self) -> str:
        return self.message


def _range_text(name: str, low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    lo = "" if low is None else f"{low!r} {'<' if low_open else '<='} "
    hi = "" if high is None else f" {'<' if high_open else '<='} {high!r}"
    return f"{lo}{name}{hi}"


def check_count(name: str, value: object, low: int = 0, high: int | None = None) -> int:
    """``value`` as a Python ``int`` in ``[low, high]``, or :class:`ParameterError`.

    Parameters
    ----------
    name : str
        The parameter's name as the user spells it (API field = CLI flag without dashes).
    value : object
        Any integral type (``int``, ``numpy.int64``, ...); ``bool`` and floats are refused.
    low, high : int, optional
        Inclusive bounds (``high=None``: no upper bound).
    """
    allowed = _range_text(name, low, high, False, False)
    if isinstance(value, bool):
        raise ParameterError(f"{name} = {value!r} is not an integer (allowed range {allowed})")
    if not isinstance(value, numbers.Integral):
        try:
            value = operator.index(value)  # anything that declares itself an integer
        except TypeError:
            raise ParameterError(f"{name} = {value!r} is not an integer (allowed range {allowed})") from None
    as_int = int(value)
    if as_int < low or (high is not None and as_int > high):
        raise ParameterError(f"{name} = {as_int!r} is outside the allowed range {allowed}")
    return as_int


def check_real(
    name: str,
    value: object,
    low: float | None = None,
    high: float | None = None,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a finite Python ``float`` in the given range, or :class:`ParameterError`.

    ``low_open``/``high_open`` make a bound strict (``0 < K`` rather than ``0 <= K``).
    """
    allowed = _range_text(name, low, high, low_open, high_open)
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} = {value!r} is not a real number (allowed range {allowed})")
    as_float = float(value)
    if not math.isfinite(as_float):
        raise ParameterError(f"{name} = {as_float!r} is not finite (allowed range {allowed})")
    below = low is not None and (as_float <= low if low_open else as_float < low)
    above = high is not None and (as_float >= high if high_open else as_float > high)
    if below or above:
        raise ParameterError(f"{name} = {as_float!r} is outside the allowed range {allowed}")
    return as_float


def check_choice(name: str, value: object, choices: Iterable[str]) -> str:
    """``value`` if it is one of ``choices``, or :class:`ParameterError` listing them."""
    choices = tuple(choices)
    if not isinstance(value, str) or value not in choices:
        raise ParameterError(f"{name} = {value!r} is not one of {', '.join(choices)}")
    return value


def check_optional(check, name: str, value: object, *args, **kwargs):
    """``None`` if ``value`` is ``None``, else ``check(name, value, *args, **kwargs)``."""
    return None if value is None else check(name, value, *args, **kwargs)


def renamed_keyword(old: str, new: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorator: the keyword ``old`` still works for ``new``, with a :class:`DeprecationWarning`.

    One name per concept: a keyword renamed to the name the rest of the API uses keeps its old
    spelling for callers that have it, and says which to use instead.
    """

    def decorate(func: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            if old in kwargs:
                name = func.__qualname__.removesuffix(".__init__")  # a class is called by its name
                if new in kwargs:
                    raise TypeError(f"{name}() got both {old}= and {new}=; give {new}= only")
                warnings.warn(f"{name}({old}=...) is spelled {new}=...", DeprecationWarning, stacklevel=2)
                kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        return wrapper

    return decorate


def renamed_attribute(owner: str, old: str, new: str) -> property:
    """A read-only property ``old`` that returns attribute ``new``, with a :class:`DeprecationWarning`.

    The attribute's counterpart of :func:`renamed_keyword` (``owner`` names the class in the warning).
    """

    def get(self: Any) -> Any:
        warnings.warn(f"{owner}.{old} is spelled {owner}.{new}", DeprecationWarning, stacklevel=2)
        return getattr(self, new)

    return property(get, doc=f"Former spelling of :attr:`{new}`, with a :class:`DeprecationWarning`.")


def renamed_globals(module: str, renamed: dict[str, str], namespace: dict[str, Any]) -> Callable[[str], Any]:
    """A module's ``__getattr__``: each former name in ``renamed`` gives the value of its new
    name in ``namespace`` (the module's globals), with a :class:`DeprecationWarning`."""

    def __getattr__(name: str) -> Any:
        if name not in renamed:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        new = renamed[name]
        warnings.warn(f"{module}.{name} is spelled {module}.{new}", DeprecationWarning, stacklevel=2)
        return namespace[new]

    return __getattr__
