"""A store on a read-only file system is read (a report, the dashboard) without writing anything beside it.

SQLite reads a WAL-mode file through a shared-memory file it creates beside the store; on a read-only mount
it cannot, and ``rivercal report`` failed with "unable to open database file". The mount is a real one: a
read-only bind mount in a mount namespace of the test's own (``unshare -rm``, no privileges needed), in which
a fresh Python process opens the store as the report does.
"""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from tests.dashboard_store import build_store

READ = """
import sys
from rivercal.store import Store, StoreError
try:
    with Store(sys.argv[1], readonly=True) as store:
        print(len(store.cycles(store.get_run("dash"))), store.integrity_check())
except StoreError as exc:
    print("StoreError:", exc)
"""


def _unshare() -> str:
    path = shutil.which("unshare")
    if path is None or subprocess.run([path, "-rm", "true"], capture_output=True).returncode != 0:
        pytest.skip("this system gives no mount namespaces to unprivileged users (unshare -rm): no read-only "
                    "mount can be made for the test")
    return path


def _read_on_readonly_mount(folder: Path, mount: Path) -> str:
    script = (f"mount --bind -o ro {folder} {mount} && touch {mount}/probe 2>/dev/null && echo WRITABLE; "
              f"{sys.executable} -c '{READ}' {mount}/run.sqlite")
    run = subprocess.run([_unshare(), "-rm", "sh", "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "WRITABLE" not in run.stdout  # the mount is read-only indeed
    return run.stdout.strip()


def test_a_store_on_a_read_only_mount_is_read(tmp_path: Path) -> None:
    folder, mount = tmp_path / "store", tmp_path / "mnt"
    folder.mkdir()
    mount.mkdir()
    build_store(folder / "run.sqlite", 3)
    assert sorted(p.name for p in folder.iterdir()) == ["run.sqlite"]  # closed cleanly: no -wal, no -shm
    assert _read_on_readonly_mount(folder, mount) == "3 []"
    assert sorted(p.name for p in folder.iterdir()) == ["run.sqlite"]


def test_a_write_ahead_log_not_yet_in_the_store_is_not_skipped_silently(tmp_path: Path) -> None:
    """A service killed on a writable mount leaves committed cycles in the -wal file: reading without them is wrong."""
    folder, mount = tmp_path / "store", tmp_path / "mnt"
    folder.mkdir()
    mount.mkdir()
    build_store(folder / "run.sqlite", 3)
    keep = sqlite3.connect(folder / "run.sqlite")  # a writer that has not checkpointed: the change is in the log
    keep.execute("PRAGMA wal_autocheckpoint = 0")
    keep.execute("UPDATE runs SET status = 'stopped'")
    keep.commit()
    try:
        (folder / "run.sqlite-shm").unlink()  # as a reboot leaves it: the log, but no shared memory
        out = _read_on_readonly_mount(folder, mount)
    finally:
        keep.close()
    assert out.startswith("StoreError:") and "write-ahead log run.sqlite-wal holds changes not yet in the store" \
        in out and "copy the store and that file to a writable folder" in out
