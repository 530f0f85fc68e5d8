"""``warpratchet verify FILE``: check every checksum and value of an archive or sweep file.

Exit status 0 when the file is clean, 1 when something is damaged (each problem on its own
line, ``FILE: damaged: ...``), 2 when FILE is missing or is not an archive or sweep file at all,
3 when another process is using it (a run writing it: verify it once the run is done).
Format v1 files (release 0.1.0) are checked too; v1 sweep files carry no checksums, which the
report says.
"""

from __future__ import annotations

import argparse
import os
import sys

from .common import UsageError, emit_json

#: Exit status for a file another process is using (not damaged, not the wrong file: try later).
IN_USE = 3
#: The first bytes of every HDF5 file (a file without them is not one: a usage error, exit 2).
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def add(sub) -> None:
    p = sub.add_parser("verify", help="check every checksum and value of an archive or sweep file")
    p.add_argument("file", help="HDF5 archive (run --out) or sweep file (sweep --out)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _kind(path: str) -> str | None:
    """``"archive"``, ``"sweep"`` or None (unknown), from the root ``format`` attribute."""
    from ..files import open_h5
    from ..spec import attr_value

    with open_h5(path, locking=False) as f:
        fmt = attr_value(f.attrs.get("format", b""))
    return {"warpratchet-archive": "archive", "warpratchet-sweep": "sweep"}.get(fmt)


def command(args: argparse.Namespace) -> int:
    from ..archive import ArchiveError, verify_archive
    from ..errors import FileFormatError
    from ..sweep import verify_sweep

    path = args.file
    if not os.path.isfile(path):
        raise UsageError(f"verify: {path}: no such file")
    with open(path, "rb") as fh:
        if fh.read(8) != _HDF5_SIGNATURE:
            raise UsageError(f"verify: {path} is not an HDF5 file (not an archive or sweep file)")
    from ..files import claim

    try:  # a file a run is writing may show a write in progress: verify it once the run is done
        os.close(claim(path, exclusive=True))
    except BlockingIOError as exc:
        print(f"warpratchet: verify: {exc}", file=sys.stderr)
        return IN_USE
    checked: dict = {}
    try:
        kind = _kind(path)
    except OSError as exc:  # an HDF5 file that does not open: its superblock or root is damaged
        problems = [f"the file does not open ({str(exc).strip().splitlines()[0]})"]
    else:
        if kind is None:
            raise UsageError(f"verify: {path} is an HDF5 file but not a warpratchet archive or sweep file")
        try:
            problems, checked = (verify_archive if kind == "archive" else verify_sweep)(path)
        except (ArchiveError, FileFormatError) as exc:
            problems = [str(exc).removeprefix(f"{path}: ")]
    if args.json:
        emit_json({"file": path, "ok": not problems, "problems": problems, "checked": checked})
    else:
        for problem in problems:
            print(f"{path}: damaged: {problem}")
        if not problems:
            what = f"{checked['format']} v{checked['format_version']}"
            print(
                f"{path}: ok ({what}: {checked['datasets']} datasets, {checked['attributes']} attributes, "
                f"{checked['bytes']} bytes of data checked)"
            )
        if checked.get("note"):
            print(f"{path}: note: {checked['note']}")
    return 1 if problems else 0
