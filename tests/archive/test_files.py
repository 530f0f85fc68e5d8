"""warpratchet._files: the file-safety mechanisms every writer shares (archives, recordings, sweeps).

The archive tests exercise them end to end (kill -9, force, files in use); these pin down each
mechanism on its own, so that a new writer can rely on them.
"""

from __future__ import annotations

import os
import shutil
import stat

import h5py
import numpy as np
import pytest

from warpratchet._files import check_new_path, claim, open_h5_reader, publish, sync_h5, temporary_beside


def test_check_new_path_refuses_existing_files_and_missing_folders(tmp_path):
    new = tmp_path / "new.h5"
    assert check_new_path(new) is False
    new.write_bytes(b"user data")
    with pytest.raises(FileExistsError, match=r"new.h5 exists; refusing to overwrite it \(hint\)"):
        check_new_path(new, hint=" (hint)")
    assert check_new_path(new, force=True) is True
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    with pytest.raises(FileExistsError, match="refusing to overwrite"):
        check_new_path(tmp_path / "dangling")
    with pytest.raises(FileExistsError, match="is not a regular file"):
        check_new_path(tmp_path, force=True)
    with pytest.raises(FileNotFoundError, match="the folder .*no does not exist"):
        check_new_path(tmp_path / "no" / "such.h5")
    assert new.read_bytes() == b"user data"


def test_publish_never_clobbers_a_file_that_appeared(tmp_path):
    path = tmp_path / "out.bin"
    with pytest.raises(FileExistsError, match="refusing to overwrite"):
        with temporary_beside(path) as tmp:
            with open(tmp, "wb") as fh:
                fh.write(b"new")
            path.write_bytes(b"raced")  # another writer took the name meanwhile
            publish(tmp, path, replace=False)
    assert path.read_bytes() == b"raced"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]  # the temporary is gone


def test_publish_replaces_atomically_with_the_usual_permissions(tmp_path):
    path = tmp_path / "out.bin"
    path.write_bytes(b"old")
    with temporary_beside(path) as tmp:
        assert os.path.dirname(tmp) == str(tmp_path) and os.path.basename(tmp).startswith(".out.bin.")
        with open(tmp, "wb") as fh:
            fh.write(b"new")
        publish(tmp, path, replace=True)
    assert path.read_bytes() == b"new"
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask  # not mkstemp's private 0600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_claim_refuses_a_file_another_holder_locked(tmp_path):
    path = tmp_path / "f"
    path.write_bytes(b"")
    shared = claim(path, exclusive=False)
    try:
        os.close(claim(path, exclusive=False))  # readers share
        with pytest.raises(BlockingIOError, match="in use by another process"):
            claim(path, exclusive=True)
    finally:
        os.close(shared)
    os.close(claim(path, exclusive=True))  # free once released


def test_h5_reader_opens_a_file_a_writer_left_open_in_swmr_mode(tmp_path):
    path, killed = tmp_path / "live.h5", tmp_path / "killed.h5"
    with h5py.File(path, "w", libver="latest") as f:
        f.create_dataset("n", data=np.array([7], np.int64), chunks=(1,), maxshape=(None,))
        f.swmr_mode = True
        sync_h5(f)
        shutil.copy(path, killed)  # the bytes a killed SWMR writer leaves: still marked open
    with pytest.raises(OSError, match="already open for write"):
        open_h5_reader(killed)
    with open_h5_reader(killed, swmr=True) as r:
        assert r["n"][0] == 7
    with open_h5_reader(path) as r:  # closed cleanly: opens normally
        assert r["n"][0] == 7


def test_writer_marked_reads_the_superblock_flags(tmp_path):
    """open_h5 decides SWMR-read from the superblock's mark, never from a failed normal open: HDF5
    checks a live file's size before its mark, and a live writer's allocated-but-unwritten tail
    gave readers a false "truncated file" (issue 13.4)."""
    from warpratchet._files import LIBVER, open_h5, writer_marked

    live, killed, closed, old = (tmp_path / n for n in ("live.h5", "killed.h5", "closed.h5", "old.h5"))
    with h5py.File(live, "w", libver=LIBVER) as f:
        f.create_dataset("n", data=np.array([3], np.int64), chunks=(1,), maxshape=(None,))
        f.swmr_mode = True
        sync_h5(f)
        assert writer_marked(live)
        shutil.copy(live, killed)
    assert writer_marked(killed) and not writer_marked(live)
    shutil.copy(live, closed)
    with h5py.File(old, "w") as f:  # HDF5's earliest format: superblock v0, no such mark
        f["n"] = 1
    assert not writer_marked(old) and not writer_marked(closed)
    for path in (killed, closed, old):
        with open_h5(path) as f:
            assert int(np.asarray(f["n"][()]).ravel()[0]) in (1, 3)
    # A truncated file that no writer has open is still an error at once.
    closed.write_bytes(closed.read_bytes()[:-64])
    with pytest.raises(OSError, match="truncated file"):
        open_h5(closed)
