"""``python -m viz <command> ...``: dispatch to viz.record, viz.scenes or viz.figures."""

from __future__ import annotations

import importlib
import sys

COMMANDS = {
    "record": ("viz.record", "replay an archive's snapshots into a rerun .rrd"),
    "scenes": ("viz.scenes", "record the paper's phase-space scenes (Figs. 1, 2, 4) as .rrd"),
    "figures": ("viz.figures", "regenerate the paper's figures (PNG and PDF)"),
}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] not in COMMANDS:
        lines = [f"  {name:8s} {help_}" for name, (_, help_) in COMMANDS.items()]
        print("usage: python -m viz {" + ",".join(COMMANDS) + "} ...\n" + "\n".join(lines), file=sys.stderr)
        return 2
    module = importlib.import_module(COMMANDS[argv[0]][0])
    return module.main(argv[1:])


if __name__ == "__main__":
    sys.exit(main())
