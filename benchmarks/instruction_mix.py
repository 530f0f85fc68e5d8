"""Instruction mix of the step loop of the compiled CPU kernels (object-code evidence of vectorisation).

Compiles (or loads from Warp's kernel cache) the CPU module of :mod:`warpratchet.kernels`,
disassembles its object file with ``objdump -d`` and, for each kernel, finds the step loop: the
innermost loop (a backward jump and its target) that contains the ``floor`` instruction
(``vrndscalepd``, or ``vroundpd``/``roundsd`` on CPUs without AVX-512). Its instructions are
counted by register width: packed 512-bit (``zmm``), 256-bit (``ymm``), 128-bit (``xmm``),
scalar float (``...sd``/``...ss`` on ``xmm``), and the rest (integer, masks, branches); stack
accesses (``(%rsp)``) count spills. ``points per pass`` is the lanes one pass of the loop
advances (``INTERLEAVE``, twice that for a kernel whose Warp thread takes two blocks of lanes),
so ``instructions per point-step`` compares kernels of any width.

``--asm`` prints the first kernel's step loop instead, without its branches, as text that
``llvm-mca`` reads (the port-throughput bound of one pass, ``benchmarks/README.md``).

Usage::

    python benchmarks/instruction_mix.py [--json]
    python benchmarks/instruction_mix.py --object OLD.o --function advance_map_ --points 8
    python benchmarks/instruction_mix.py --function advance_map_ --asm | llvm-mca -mcpu=znver3
"""

from __future__ import annotations

import argparse
import collections
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

CLASSES = ("zmm", "ymm", "xmm", "scalar", "other")
FLOOR = re.compile(r"rndscale|round")
COMMENT = re.compile(r"\s*#.*$")


def _disassemble(obj: Path) -> dict[str, list[tuple[int, str, str]]]:
    """``{function: [(address, mnemonic, operands), ...]}`` of an object file."""
    text = subprocess.run(
        ["objdump", "-d", "--no-show-raw-insn", str(obj)], capture_output=True, text=True
    ).stdout
    functions: dict[str, list[tuple[int, str, str]]] = {}
    current = None
    for line in text.splitlines():
        head = re.match(r"^[0-9a-f]+ <(.+)>:", line)
        if head:
            current = functions.setdefault(head.group(1), [])
            continue
        insn = re.match(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
        if insn and current is not None:
            current.append((int(insn.group(1), 16), insn.group(2), insn.group(3)))
    return functions


def _kind(mnemonic: str, operands: str) -> str:
    if "zmm" in operands:
        return "zmm"
    if "ymm" in operands:
        return "ymm"
    if "xmm" in operands:
        return "scalar" if mnemonic.endswith(("sd", "ss")) else "xmm"
    return "other"


def loops_of(code: list[tuple[int, str, str]]) -> list[tuple[int, int]]:
    """``(first, last)`` object addresses of each loop (a backward jump and its target) of a
    function, innermost (shortest) first; nested loops share instructions."""
    found = set()
    for address, mnemonic, operands in code:
        target = re.match(r"([0-9a-f]+)", operands)
        if mnemonic.startswith("j") and target and int(target.group(1), 16) <= address:
            found.add((int(target.group(1), 16), address))
    return sorted(found, key=lambda span: (span[1] - span[0], span[0]))


def step_loop(code: list[tuple[int, str, str]]) -> list[tuple[str, str]] | None:
    """``(mnemonic, operands)`` of the innermost loop that contains a floor instruction (None if
    there is none)."""
    loops = loops_of(code)
    with_floor = [
        (hi - lo, lo, hi) for lo, hi in loops if any(lo <= a <= hi and FLOOR.search(m) for a, m, _ in code)
    ]
    if not with_floor:
        return None
    _, lo, hi = min(with_floor)
    return [(m, o) for a, m, o in code if lo <= a <= hi]


def step_loop_mix(code: list[tuple[int, str, str]]) -> dict[str, Any] | None:
    """Counts for the innermost loop that contains a floor instruction (None if there is none)."""
    body = step_loop(code)
    if body is None:
        return None
    counts = collections.Counter(_kind(m, o) for m, o in body)
    return {
        "instructions": len(body),
        **{k: counts.get(k, 0) for k in CLASSES},
        "floor": sum(1 for m, _ in body if FLOOR.search(m)),
        "stack_accesses": sum(1 for _, o in body if "(%rsp)" in o),
    }


def warpratchet_object(kernel: Any = None) -> tuple[Path, int]:
    """The object file of the CPU module of ``kernel`` (an ``AdvanceKernel``; default
    ``advance_map``, whose module holds the indicators too) in Warp's kernel cache, loaded (or
    compiled) first, and the points one pass of its step loop advances."""
    import warp as wp

    from warpratchet import kernels

    kernel = kernels.advance_map if kernel is None else kernel
    kernels.init_warp()
    kernel.load("cpu")
    module = kernel.cpu.module
    (block_dim,) = {block_dim for _, block_dim in module.execs}  # the variant loaded on the CPU
    build = Path(wp.config.kernel_cache_dir) / module.get_module_identifier(block_dim)
    # a paired kernel's thread (``_step.PAIRED``) advances two blocks of lanes in each pass
    lanes = kernels.INTERLEAVE * (2 if kernel.cpu_paired else 1)
    return max(build.glob("*.o"), key=lambda p: p.stat().st_mtime), lanes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="instruction_mix.py", description=__doc__.splitlines()[0])
    parser.add_argument("--object", type=Path, help="an object file (default: warpratchet's CPU kernels)")
    parser.add_argument("--function", action="append", help="function name prefix (repeatable)")
    parser.add_argument("--points", type=int, help="points one pass of the loop advances")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    parser.add_argument("--asm", action="store_true", help="print the step loop for llvm-mca")
    args = parser.parse_args(argv)
    if shutil.which("objdump") is None:
        print("instruction_mix.py: objdump not found (binutils)", file=sys.stderr)
        return 2
    obj, points = (args.object, args.points or 1) if args.object else warpratchet_object()
    prefixes = args.function or ["advance_map_", "advance_map_indicators_"]
    functions = _disassemble(obj)
    rows = {}
    for prefix in prefixes:
        # Warp names a kernel's CPU entry point <kernel>_<hash>_cpu_forward.
        entry = re.compile(re.escape(prefix) + r"[0-9a-f]+_cpu_forward$")
        name = next((f for f in functions if entry.match(f) or f == prefix), None)
        if name is None:
            continue
        if args.asm:
            body = step_loop(functions[name]) or []
            # branches and padding dropped: llvm-mca treats the text as one loop body
            kept = [(m, COMMENT.sub("", o)) for m, o in body if not m.startswith(("j", "nop"))]
            print("\n".join(f"{m} {o}" for m, o in kept))
            return 0
        mix = step_loop_mix(functions[name])
        if mix is not None:
            mix["points_per_pass"] = points
            mix["instructions_per_point_step"] = mix["instructions"] / points
            rows[prefix] = {"function": name, **mix}
    if args.json:
        print(json.dumps({"object": str(obj), "step_loops": rows}))
        return 0
    print(f"Step loops of {obj}")
    head = f"{'kernel':<26}{'instr':>6}" + "".join(f"{k:>7}" for k in CLASSES) + f"{'floor':>7}{'spills':>8}"
    head += f"{'points':>8}{'instr/pt-step':>15}"
    print(head)
    for prefix, row in rows.items():
        print(
            f"{prefix.rstrip('_'):<26}{row['instructions']:>6}"
            + "".join(f"{row[k]:>7}" for k in CLASSES)
            + f"{row['floor']:>7}{row['stack_accesses']:>8}{row['points_per_pass']:>8}"
            + f"{row['instructions_per_point_step']:>15.1f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
