"""Cost of a run's history: wall time with a History observer over wall time without.

Each case advances a fresh strip ensemble (Eq. B) at K = 3, b1 = 0.1, b2 = 0.01 (seed 1) by
``steps`` iterations twice per repetition, alternately

* without a history: ``Ensemble.run(steps)`` with the default chunking, and
* with one: ``Ensemble.run(steps, [History()])``, what ``warpratchet run`` records by default:
  rows (a summary of every point) at >= 8 log-spaced steps per decade, n/2 and n, and the
  momentum gains of 4096 points at 64 block ends, each of those steps ending a chunk,

and reports the ratio of the best wall times (the budget: under 1.05 at 10^4 points x
1.2e5 steps and at 10^6 points), the ratio of the best process CPU times, and the history's own
share measured directly: the seconds spent inside the observer over the kernel seconds of the
same run (the steadiest of the three on a shared machine; it leaves out what the extra chunk ends
cost the kernel, which the wall ratio includes). Both runs must end in bitwise equal states (a
history never changes results); the script exits with status 1 if not.

The cost per row is about one summary, ~25-30 kernel point-steps per point, and the number of rows
grows like log n, so the share falls like (log n)/n: the same for any ensemble size at a given n.

Usage::

    python benchmarks/history_overhead.py                 # 10^4 x 1.2e5 (best of 3), 10^6 x 1.2e5 (~8 min)
    python benchmarks/history_overhead.py --json          # one JSON object on stdout
    python benchmarks/history_overhead.py --quick --json  # smoke test, a few seconds
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from _sink_overhead import Timed, case_row, columns_for, compare, finish, log, measure_cases, options, warm_up

from warpratchet.history import History

BUDGET = 1.05
#: (points, steps): the CLI default first, then 10^6 points at the paper's n.
CASES = [(10_000, 120_000), (1_000_000, 120_000)]
QUICK_CASES = [(10_000, 20_000), (100_000, 2_000)]
#: The text table: (header, key, format).
COLUMNS = columns_for(
    [("rows", "rows", "d"), ("blocks", "blocks", "d")],
    ("history s", "history"),
    ("history/kernel", "history"),
)


def measure(points: int, steps: int, repeat: int, folder: Path) -> dict[str, Any]:
    """Best-of-``repeat`` wall and CPU times with and without the history, alternating."""

    def recorded(ens, rep: int) -> dict[str, Any]:
        history = History()
        timed = Timed(history)
        ens.run(steps, [timed])
        return {
            "share": timed.seconds / timed.kernel,
            "rows": len(history.rows["step"]),
            "blocks": len(history.block_rows["block_step"]),
        }

    t = compare(points, steps, repeat, recorded)
    shares = [info["share"] for info in t["measured"]]
    log(f"  history {100 * min(shares):.2f}% of the kernel time (best)")
    last = t["measured"][-1]
    return case_row(
        points, steps, {"rows": last["rows"], "blocks": last["blocks"]}, t, ("history", "history"), shares
    )


def main(argv: list[str] | None = None) -> int:
    args, repeat = options(__doc__, argv, repeat=3)
    warm_up()
    cases = QUICK_CASES if args.quick else CASES
    results = []
    for points, steps in cases:  # 10^6 points: one repetition (a run takes a few minutes)
        reps = repeat if points * steps <= 2e9 else 1
        results += measure_cases([(points, steps)], reps, measure, "warpratchet-history-bench-")
    summary = {
        "within_budget": all(r["wall_ratio"] <= BUDGET for r in results),
        "share_within_budget": all(r["history_share_of_kernel"] <= BUDGET - 1 for r in results),
    }
    note = f"budget: wall ratio <= {BUDGET} (history share <= {BUDGET - 1:.0%})"
    return finish(args, BUDGET, summary, results, COLUMNS, note)


if __name__ == "__main__":
    sys.exit(main())
