"""What the overhead benchmarks share (archive, recording, history): a run with and without a sink.

Not a script. Each repetition advances a fresh strip ensemble (Eq. B) at K = 3, b1 = 0.1,
b2 = 0.01 (seed 1) by ``steps`` iterations twice, first plainly (``Ensemble.run(steps)`` with
the default chunking), then with the sink under test, and keeps the best wall and process CPU
times of each: ratios taken within one run are the numbers to read on a shared machine. Both
runs must end in bitwise equal states, since a sink never changes results.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from throughput_contenders import Clock, Timing

from warpratchet import Ensemble, MapParams, Observer
from warpratchet.ensemble import STATE_FIELDS

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
INIT, SEED = "strip", 1


class Timed(Observer):
    """Forwards to an observer (its ``next_stop`` too, if it has one) and adds up the seconds spent
    in it (``seconds``) and in the kernel between its calls (``kernel``)."""

    def __init__(self, inner: Observer) -> None:
        self.inner = inner
        self.seconds = 0.0
        self.kernel = 0.0
        if callable(getattr(inner, "next_stop", None)):
            self.next_stop = inner.next_stop

    def _time(self, method, *args) -> None:
        start = time.perf_counter()
        method(*args)
        self.seconds += time.perf_counter() - start

    def begin(self, ensemble, target_step):
        self._time(self.inner.begin, ensemble, target_step)

    def after_chunk(self, ensemble, seconds):
        self.kernel += seconds
        self._time(self.inner.after_chunk, ensemble, seconds)

    def end(self, ensemble):
        self._time(self.inner.end, ensemble)


def log(message: str) -> None:
    """Progress on stderr (stdout carries the table or the JSON)."""
    print(message, file=sys.stderr, flush=True)


def fresh(points: int, cls: type[Ensemble] = Ensemble) -> Ensemble:
    return cls.sample(PARAMS, points, INIT, SEED)


def warm_up() -> None:
    """Compile the kernel (or load it from the cache) outside the timings."""
    fresh(64).run(16)


def options(
    doc: str,
    argv: list[str] | None,
    repeat: int,
    extra: Callable[[argparse.ArgumentParser], None] | None = None,
) -> tuple[argparse.Namespace, int]:
    """The common options, parsed: ``--repeat N`` (best of N; default ``repeat``, 1 with
    ``--quick``), ``--quick``, ``--json``, and what ``extra(parser)`` adds. Returns the arguments
    and the repetitions."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    if extra is not None:
        extra(p)
    p.add_argument(
        "--repeat",
        "--repeats",
        dest="repeat",
        type=int,
        default=None,
        help=f"timings per case, best kept (default {repeat}; 1 with --quick)",
    )
    p.add_argument("--quick", action="store_true", help="small cases, one repetition (smoke test)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = p.parse_args(argv)
    if args.repeat is None:
        return args, 1 if args.quick else repeat
    if args.repeat < 1:
        p.error(f"--repeat {args.repeat} is outside the allowed range >= 1")
    return args, args.repeat


def measure_cases(
    cases: list[tuple[int, int]], repeat: int, measure: Callable[..., dict[str, Any]], prefix: str
) -> list[dict[str, Any]]:
    """``measure(points, steps, repeat, folder)`` of every case, writing into a temporary folder."""
    results = []
    with tempfile.TemporaryDirectory(prefix=prefix) as folder:
        for points, steps in cases:
            log(f"{points} points x {steps} steps")
            results.append(measure(points, steps, repeat, Path(folder)))
    return results


def compare(
    points: int,
    steps: int,
    repeats: int,
    run_with_sink: Callable[[Ensemble, int], dict[str, Any]],
    after: Callable[[dict[str, Any]], None] | None = None,
    cls: type[Ensemble] = Ensemble,
) -> dict[str, Any]:
    """Best-of-``repeats`` times of a plain run and of a run with the sink, alternating.

    Parameters
    ----------
    run_with_sink : callable
        ``run_with_sink(ensemble, rep)`` makes the sink, advances ``ensemble`` by ``steps`` with
        it, closes it, and returns what it measured; all of it is inside the timing.
    after : callable, optional
        Called with that dict after the timing (e.g. to delete the file written).
    cls : type
        The ensemble class (a subclass emulating a faster kernel, see recording_overhead.py).

    Returns
    -------
    dict
        ``plain``, ``plain_cpu``, ``sink``, ``sink_cpu`` (best seconds), ``identical`` (every
        pair of runs ended in bitwise equal states) and ``measured`` (the dicts of every
        repetition, in order).
    """
    plain: list[Timing] = []
    sink: list[Timing] = []
    measured = []
    identical = True
    for rep in range(repeats):
        ens = fresh(points, cls)
        with Clock() as clock:
            ens.run(steps)
        plain.append(clock.timing)
        reference = ens.state()
        del ens

        ens = fresh(points, cls)
        with Clock() as clock:
            info = run_with_sink(ens, rep)
        sink.append(clock.timing)
        identical &= all(np.array_equal(reference[k], ens.array(k)) for k in STATE_FIELDS)
        measured.append(info)
        if after is not None:
            after(info)
        del ens
        log(f"  {points} x {steps}: plain {plain[-1].seconds:.3f} s, with the sink {sink[-1].seconds:.3f} s")
    return {
        "plain": min(t.seconds for t in plain),
        "plain_cpu": min(t.cpu_seconds for t in plain),
        "sink": min(t.seconds for t in sink),
        "sink_cpu": min(t.cpu_seconds for t in sink),
        "identical": identical,
        "measured": measured,
    }


def case_row(
    points: int,
    steps: int,
    own: dict[str, Any],
    t: dict[str, Any],
    names: tuple[str, str],
    shares: list[float],
) -> dict[str, Any]:
    """A case's row: ``points``, ``steps``, the benchmark's ``own`` columns, then the timings of
    :func:`compare`'s ``t``: best plain and ``{sink}_seconds``, their wall and CPU ratios, the best
    ``{share}_share_of_kernel`` of ``shares`` and ``identical``, where ``names = (sink, share)``."""
    sink, share = names
    return {
        "points": points,
        "steps": steps,
        **own,
        "plain_seconds": t["plain"],
        f"{sink}_seconds": t["sink"],
        "wall_ratio": t["sink"] / t["plain"],
        "cpu_ratio": t["sink_cpu"] / t["plain_cpu"],
        f"{share}_share_of_kernel": min(shares),
        "identical": t["identical"],
    }


def columns_for(
    own: list[tuple[str, str, str]], sink: tuple[str, str], share: tuple[str, str]
) -> list[tuple[str, str, str]]:
    """The table columns of :func:`case_row`'s rows, ``(header, key, format)``: ``own`` are the
    benchmark's, ``sink`` and ``share`` are ``(header, name)`` of its timing columns."""
    return [
        ("points", "points", "d"), ("steps", "steps", "d"), *own,
        ("plain s", "plain_seconds", ".3f"), (sink[0], f"{sink[1]}_seconds", ".3f"),
        ("wall x", "wall_ratio", ".3f"), ("cpu x", "cpu_ratio", ".3f"),
        (share[0], f"{share[1]}_share_of_kernel", ".2f%"), ("same", "identical", "yes"),
    ]  # fmt: skip


def finish(
    args: argparse.Namespace,
    budget: float,
    summary: dict[str, Any],
    cases: list[dict[str, Any]],
    columns: list[tuple[str, str, str]],
    note: str,
) -> int:
    """Print the report of :func:`case_row` rows (:func:`emit`: ``budget``, the benchmark's
    ``summary``, ``quick`` and the ``cases``) and return the exit status: 0 if every case ended
    in bitwise equal states, else 1."""
    report = {"budget": budget, **summary, "quick": args.quick, "cases": cases}
    emit(report, args.json, columns, note)
    return 0 if all(case["identical"] for case in cases) else 1


def print_table(rows: list[dict[str, Any]], columns: list[tuple[str, str, str]]) -> None:
    """A right-aligned text table: ``columns`` are ``(header, key, format spec)``; a spec ending
    in ``%`` prints the value times 100 with a percent sign, ``"yes"`` prints yes or NO."""

    def cell(row: dict[str, Any], key: str, spec: str) -> str:
        value = row[key]
        if spec == "yes":
            return "yes" if value else "NO"
        if spec.endswith("%"):
            return f"{100 * value:{spec[:-1]}}%"
        return f"{value:{spec}}"

    widths = [max(len(header), *(len(cell(r, key, spec)) for r in rows)) for header, key, spec in columns]
    print(" ".join(f"{header:>{w}}" for (header, _, _), w in zip(columns, widths, strict=True)))
    for r in rows:
        print(
            " ".join(f"{cell(r, key, spec):>{w}}" for (_, key, spec), w in zip(columns, widths, strict=True))
        )


def emit(report: dict[str, Any], as_json: bool, columns: list[tuple[str, str, str]], note: str) -> None:
    """The report as one JSON object on stdout, or its ``cases`` as a table followed by ``note``."""
    if as_json:
        print(json.dumps(report))
        return
    print_table(report["cases"], columns)
    print(note)
