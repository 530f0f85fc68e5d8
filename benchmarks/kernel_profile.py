"""Where a CPU kernel spends its time, measured: ``perf`` samples mapped onto the kernel's object code.

The measured companion of ``instruction_mix.py`` (which counts a loop's instructions) and of the
``llvm-mca`` bounds in ``benchmarks/README.md`` (which model them). Each kernel (``map``,
``indicators``, ``transport``) advances the ensemble of ``kernel_ceilings.py`` launch after launch
in a child process run under ``perf record -e cpu-clock`` (a timer event: it needs no hardware
counters, so it works in a virtual machine). Warp's CPU loader copies the kernel module's code to
memory of its own, which ``perf`` sees without symbols; the script finds where: the page-aligned
base at which the samples fall on instruction boundaries of the module's object file
(``objdump -d``), every one of them inside the kernel's function. It then reports, for the
kernel's function:

* its share of the CPU time of the launches (the rest is Warp's launch and the C library's calls);
* each loop (a backward jump and its target), the largest share first: its own instructions (not
  those of the loops inside it), their share of the function's samples and the nanoseconds per
  point-step that share stands for; the step loop is the smallest loop with the floor
  instruction, as in ``instruction_mix.py``.

Samples land on the instruction after the one that waited (skid), so read loops, not single
instructions.

Usage::

    python benchmarks/kernel_profile.py                        # 3 kernels, 10^6 points x 4000 steps
    python benchmarks/kernel_profile.py --kernel transport --json
    python benchmarks/kernel_profile.py --quick --json         # smoke test: 20 000 points x 400 steps

Needs ``perf`` (``kernel.perf_event_paranoid`` at most 2) and ``objdump``: exits 2 where either is
missing, 1 with perf's message where it cannot sample.
"""

from __future__ import annotations

import argparse
import bisect
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from instruction_mix import FLOOR, _disassemble, loops_of, warpratchet_object

KERNEL_NAMES = ("map", "indicators", "transport")
PAGE = 4096
# perf's sampling rate: samples per CPU second of the launches.
FREQUENCY = 4999


# -- the child: the kernel's launches under perf ---------------------------------------------------
def _child(kernel: str, points: int, steps: int, launch: int, out: Path, control: list[Path]) -> None:
    """Advance the kernel's ensemble ``steps`` in launches of ``launch`` on one thread, perf's events
    enabled only then (``control``: its control and acknowledgement FIFOs); write the object file,
    the kernel, the launches' CPU seconds and point-steps to ``out`` (JSON)."""
    from kernel_ceilings import KERNELS, _ensemble

    from warpratchet import kernels

    def tell_perf(command: str) -> None:
        with open(control[0], "w") as ctl:
            ctl.write(command + "\n")
        with open(control[1]) as ack:
            ack.readline()

    ens = _ensemble(KERNELS[kernel], points, 1, None)  # compiled (or loaded) and warmed up
    tell_perf("enable")
    cpu = time.process_time()
    done = 0
    while done < steps:
        todo = min(launch, steps - done)
        ens._advance(todo, None)
        done += todo
    cpu = time.process_time() - cpu
    tell_perf("disable")
    obj, lanes = warpratchet_object(ens._kernel)
    report = {
        "object": str(obj),
        "kernel_key": ens._kernel.cpu.key,
        "cpu_seconds": cpu,
        "point_steps": points * steps,
        "lanes": lanes,
        "isa": kernels.CPU_ISA,
        "pid": os.getpid(),
    }
    out.write_text(json.dumps(report))


# -- mapping samples onto the object code ----------------------------------------------------------
def find_base(samples: dict[int, int], starts: list[int], lo: int, hi: int) -> int | None:
    """The load address of an object whose function spans ``[lo, hi)`` (object addresses) and whose
    instructions start at ``starts`` (sorted, in ``[lo, hi)``): the page-aligned base ``b`` at which the most
    samples (``{address: count}``) fall in ``[b + lo, b + hi)``, all of them on an instruction
    start. None if no base puts a sample there."""
    inside = set(starts)
    best, best_count = None, 0
    # a base puts the most-sampled address somewhere in the function, on an instruction
    for top in sorted(samples, key=samples.get, reverse=True)[:8]:
        for start in starts:
            base = top - start
            if base % PAGE:  # the loader places code at a page boundary
                continue
            hits = [(a - base, c) for a, c in samples.items() if lo <= a - base < hi]
            if all(offset in inside for offset, _ in hits):
                count = sum(c for _, c in hits)
                if count > best_count:
                    best, best_count = base, count
        if best is not None:
            return best
    return None


def loop_shares(code: list[tuple[int, str, str]], at: dict[int, int], top: int) -> tuple[list[dict], float]:
    """The shares of the samples ``at`` (``{object address: count}``) of a function ``code``
    (``(address, mnemonic, operands)``) by loop, the largest ``top`` first, and the share in no
    loop. Each instruction counts for the smallest loop around it, so the shares add up to 1: a
    loop's own instructions, not those of the loops inside it. The step loop is the smallest loop
    that owns a floor instruction."""
    starts = [a for a, _, _ in code]
    owner: dict[int, tuple[int, int]] = {}
    for first, last in loops_of(code):  # innermost first: the first owner is the smallest
        for address in starts[bisect.bisect_left(starts, first) : bisect.bisect_right(starts, last)]:
            owner.setdefault(address, (first, last))
    sizes = collections.Counter(owner.values())
    floors = [owner[a] for a, m, _ in code if a in owner and FLOOR.search(m)]
    step_loop = min(floors, key=sizes.__getitem__) if floors else None
    counts: collections.Counter[tuple[int, int] | None] = collections.Counter()
    for address, count in at.items():
        counts[owner.get(address)] += count
    total = sum(counts.values()) or 1
    rows = [
        {
            "first": span[0],
            "last": span[1],
            "own_instructions": sizes[span],
            "step_loop": span == step_loop,
            "share": count / total,
        }
        for span, count in counts.most_common()
        if span is not None
    ]
    return rows[:top], counts[None] / total


def profile(samples: dict[int, int], period_s: float, child: dict[str, Any], top: int) -> dict[str, Any]:
    """The kernel function's share of the launches and its loops' shares (see the module docstring)."""
    functions = _disassemble(Path(child["object"]))
    # Warp names a kernel's CPU entry point <kernel>_<hash>_cpu_forward
    entry = re.compile(re.escape(child["kernel_key"]) + r"_[0-9a-f]+_cpu_forward$")
    name = next((f for f in functions if entry.match(f)), None)
    if name is None:
        raise SystemExit(f"kernel_profile.py: no function for {child['kernel_key']!r} in {child['object']}")
    code = functions[name]
    starts = [a for a, _, _ in code]
    lo, hi = starts[0], starts[-1] + 1
    base = find_base(samples, starts, lo, hi)
    if base is None:
        raise SystemExit("kernel_profile.py: no sample fell in the kernel's code (was it run?)")
    at = {a - base: c for a, c in samples.items() if lo <= a - base < hi}
    in_function = sum(at.values())
    ns_per_point_step = child["cpu_seconds"] * 1e9 / child["point_steps"]
    function_share = in_function * period_s / child["cpu_seconds"]
    loops, outside = loop_shares(code, at, top)
    for loop in loops:  # the nanoseconds of each point-step that the loop's share stands for
        loop["ns_per_point_step"] = function_share * ns_per_point_step * loop["share"]
    return {
        "function": name,
        "base": base,
        "samples_in_function": in_function,
        "function_share_of_launches": function_share,
        "ns_per_point_step": ns_per_point_step,
        "loops": loops,
        "outside_loops": outside,
    }


def _samples(data: Path, pid: int) -> tuple[dict[int, int], float]:
    """``{address: count}`` of the user-space samples of process ``pid`` outside every file-backed
    mapping (the JIT's code), and the seconds one sample stands for."""
    text = subprocess.run(
        ["perf", "script", "-i", str(data), "-F", "pid,ip,dso,period"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    counts: collections.Counter[int] = collections.Counter()
    periods = []
    for line in text.splitlines():
        parts = line.split()  # perf prints the fields in its own order: pid, period, ip, dso
        if len(parts) < 4 or not parts[0].isdigit() or int(parts[0]) != pid:
            continue
        period, ip, dso = int(parts[1]), int(parts[2], 16), parts[3]
        periods.append(period)
        # the JIT's memory has no file: perf names it after its own symbol map or leaves it unknown
        if ip < 1 << 47 and ("perf-" in dso or "unknown" in dso or "anon" in dso):
            counts[ip] += 1
    period_s = (sum(periods) / len(periods) * 1e-9) if periods else 0.0
    return dict(counts), period_s


def measure(kernel: str, points: int, steps: int, launch: int, top: int) -> dict[str, Any]:
    """Run the child under perf and profile its samples."""
    with tempfile.TemporaryDirectory() as tmp:
        out, data = Path(tmp) / "child.json", Path(tmp) / "perf.data"
        control = [Path(tmp) / "ctl", Path(tmp) / "ack"]
        for fifo in control:
            os.mkfifo(fifo)
        command = [sys.executable, __file__, "--child", "--kernel", kernel, "--points", str(points)]
        command += ["--steps", str(steps), "--launch", str(launch), "--child-out", str(out)]
        command += ["--child-control", str(control[0]), str(control[1])]
        # events off until the child's launches begin (not the start-up, the compile, the warm-up)
        record = [
            "perf",
            "record",
            "-q",
            "-e",
            "cpu-clock",
            "-F",
            str(FREQUENCY),
            "-o",
            str(data),
            "-D",
            "-1",
        ]
        record += ["--control", f"fifo:{control[0]},{control[1]}", "--"]
        done = subprocess.run(record + command, capture_output=True, text=True)
        if done.returncode != 0 or not out.exists():
            raise SystemExit(f"kernel_profile.py: perf record failed: {done.stderr.strip()[-500:]}")
        child = json.loads(out.read_text())
        samples, period_s = _samples(data, child["pid"])
    result = profile(samples, period_s, child, top)
    return {
        "kernel": kernel,
        "isa": child["isa"],
        "lanes": child["lanes"],
        "object": child["object"],
        **result,
    }


def _print(row: dict[str, Any], points: int, steps: int, launch: int) -> None:
    print(
        f"{row['kernel']} ({row['isa']} path, {row['lanes']} lanes): {points:,} points x {steps:,} steps, "
        f"launches of {launch}, one thread; {row['ns_per_point_step']:.2f} ns per point-step"
    )
    print(
        f"  {row['function']}: {100 * row['function_share_of_launches']:.1f}% of the launches' CPU time, "
        f"{row['samples_in_function']:,} samples"
    )
    print(f"  {'loop (object addresses)':<30}{'own instr':>10}{'share':>8}{'ns/pt-step':>12}")
    for loop in row["loops"]:
        span = f"{loop['first']:x}-{loop['last']:x}" + ("  (step loop)" if loop["step_loop"] else "")
        share, ns = 100 * loop["share"], loop["ns_per_point_step"]
        print(f"  {span:<30}{loop['own_instructions']:>10}{share:>7.1f}%{ns:>12.3f}")
    print(f"  {'in no loop':<40}{100 * row['outside_loops']:>7.1f}%")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="kernel_profile.py", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--kernel", action="append", choices=KERNEL_NAMES, help="a kernel (repeatable; default all)"
    )
    parser.add_argument("--points", type=int, default=None, help="points (default 10^6)")
    parser.add_argument("--steps", type=int, default=None, help="steps in all (default 4000)")
    parser.add_argument("--launch", type=int, default=400, help="steps per launch (default 400)")
    parser.add_argument("--top", type=int, default=6, help="loops to list (default 6)")
    parser.add_argument("--quick", action="store_true", help="20 000 points x 400 steps")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--child-out", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--child-control", type=Path, nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    points = args.points if args.points is not None else (20_000 if args.quick else 1_000_000)
    steps = args.steps if args.steps is not None else (400 if args.quick else 4000)
    for name, value in (("points", points), ("steps", steps), ("launch", args.launch), ("top", args.top)):
        if value < 1:
            print(f"kernel_profile.py: error: --{name} = {value}: must be at least 1", file=sys.stderr)
            return 2
    if args.child:
        _child(args.kernel[0], points, steps, args.launch, args.child_out, args.child_control)
        return 0
    for tool in ("perf", "objdump"):
        if shutil.which(tool) is None:
            print(
                f"kernel_profile.py: error: {tool} not found (it is needed to sample and read the kernel)",
                file=sys.stderr,
            )
            return 2
    rows = [measure(k, points, steps, args.launch, args.top) for k in args.kernel or KERNEL_NAMES]
    if args.json:
        print(json.dumps({"points": points, "steps": steps, "launch": args.launch, "results": rows}))
        return 0
    for row in rows:
        _print(row, points, steps, args.launch)
    return 0


if __name__ == "__main__":
    sys.exit(main())
