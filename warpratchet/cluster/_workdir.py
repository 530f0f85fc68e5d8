"""A sharded run's workdir: which run its shards belong to, and the run's own folder.

``run.json`` names the run a workdir's shards belong to (:func:`_manifest`,
:func:`_claim_workdir`), so that no run resumes another's archives. Beside ``out`` each run has
a folder of its own (:func:`_run_folder`), and once ``out`` reads a run's folder the others go
(:func:`_remove_other_runs`). The shards' files in a workdir are
:func:`~warpratchet._cluster_archive.shard_paths`.
"""

from __future__ import annotations

import os

from ..errors import ParameterError
from ..spec import RunSpec


def _manifest(spec: RunSpec, bounds: list, transport: bool, snapshots: tuple[int, int]) -> dict:
    """What ``run.json`` of a workdir holds: the run its shards belong to."""
    import json

    run = {k: v for k, v in json.loads(spec.to_json()).items() if k not in ("threads", "device")}
    run.update(transport=transport, shards=[list(b) for b in bounds])
    if snapshots[0]:
        run.update(snapshot_every=snapshots[0], snapshot_points=snapshots[1])
    return run


#: The prefix of a run's folder in the shards folder beside ``out`` (:func:`_run_folder`).
RUN_FOLDER = "run-"


def _run_folder(run: dict) -> str:
    """The name of the folder of the run ``run`` (:func:`_manifest`) in ``out + ".shards"``: the
    same for the same run (the same command again continues it), another for another run (so a
    run that replaces ``out`` never writes where the file it replaces reads)."""
    import hashlib
    import json

    return RUN_FOLDER + hashlib.sha256(json.dumps(run, sort_keys=True).encode()).hexdigest()[:16]


def _remove_other_runs(workdir: str) -> None:
    """Remove the other runs' folders beside ``workdir`` (in ``out + ".shards"``), once ``out``
    reads ``workdir``'s: the replaced file's shards, and what runs that never published left."""
    import shutil

    parent = os.path.dirname(workdir)
    for name in os.listdir(parent):
        path = os.path.join(parent, name)
        if name.startswith(RUN_FOLDER) and path != workdir and os.path.isdir(path):
            shutil.rmtree(path)


def _claim_workdir(workdir: str | os.PathLike, run: dict) -> str:
    """``workdir`` as an absolute path, made if missing, with ``run.json`` naming the run its shards
    belong to (:func:`_manifest`); ParameterError if it holds the shards of another run (its
    archives would be resumed)."""
    import json

    workdir = os.path.abspath(os.fspath(workdir))
    manifest = os.path.join(workdir, "run.json")
    if os.path.exists(manifest):
        with open(manifest) as f:
            held = json.load(f)
        if held != run:
            differ = sorted(k for k in run.keys() | held.keys() if run.get(k) != held.get(k))
            raise ParameterError(
                f"workdir = {workdir} holds the shards of another run (it differs in {', '.join(differ)}); "
                "choose another folder or remove it"
            )
        return workdir
    os.makedirs(workdir, exist_ok=True)
    with open(manifest, "w") as f:
        json.dump(run, f, indent=1)
    return workdir
