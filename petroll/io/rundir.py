"""A run's output directory: one run at a time (a lock file naming its holder), stale files cleaned.

``DIR/petroll.lock`` holds the process that runs into DIR: its PID, host and start time, as JSON. It is
held with ``flock`` for the run's whole duration, so a lock whose process died (killed, crashed, the
machine rebooted) is free again at once and is taken over; where the file system has no ``flock``
(some network file systems), a lock of a dead process on this host is taken over, one of another host
is refused (the message says to remove it if that process is gone).
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import fcntl
import json
import os
import pathlib
import re
import socket

LOCK_NAME = "petroll.lock"

_TEMPORARY = re.compile(r"^\.(.+)\.tmp(\d+)$")
"""A temporary file of an atomic write (``.NAME.tmpPID``, petroll.io.results.atomic_write and others)."""


class DirectoryBusy(Exception):
    """Another process holds the output directory (the message names it)."""


class RunLock:
    """The lock of one output directory, held by this process (:meth:`acquire` / :meth:`release`)."""

    def __init__(self, directory: str | pathlib.Path, what: str = "petroll"):
        self.directory = pathlib.Path(directory)
        self.path = self.directory / LOCK_NAME
        self.what = what
        self.fd = -1

    def acquire(self) -> None:
        """Take the lock, or raise DirectoryBusy naming its holder. OSError if the file cannot be made."""
        for _ in range(10):  # the holder may release (unlink) between our open and our flock: again
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                held = _try_flock(fd)
                if held is False:
                    raise DirectoryBusy(self._busy(_holder(fd)))
                if held is None and not _stale(_holder(fd)):  # no flock here: judge by the PID
                    raise DirectoryBusy(self._busy(_holder(fd), unsure=True))
                if os.fstat(fd).st_ino != os.stat(self.path).st_ino:
                    os.close(fd)
                    continue
            except BaseException:
                with contextlib.suppress(OSError):
                    os.close(fd)
                raise
            self.fd = fd
            try:
                os.ftruncate(fd, 0)
                os.pwrite(fd, json.dumps(_me(self.what)).encode() + b"\n", 0)
                os.fsync(fd)
            except BaseException:  # a full disk: no lock left behind, held or on disk
                self.release()
                raise
            return
        raise DirectoryBusy(f"{self.directory}: in use (its lock file {self.path} keeps changing hands)")

    def release(self) -> None:
        """Remove the lock file and let it go (the file first: a process waiting on it then sees a new one)."""
        if self.fd < 0:
            return
        with contextlib.suppress(OSError):
            self.path.unlink()
        os.close(self.fd)
        self.fd = -1

    def _busy(self, holder: dict, unsure: bool = False) -> str:
        who = (f"PID {holder.get('pid', '?')} on host {holder.get('host', '?')}, since "
               f"{holder.get('started', '?')}" if holder else "another process")
        doing = f" ({holder['what']})" if holder.get("what") else ""
        hint = (f"; if that process is gone, remove {self.path}" if unsure else
                "; wait for it to finish, or choose another output directory")
        return f"{self.directory}: in use by {who}{doing}{hint}"


def _try_flock(fd: int) -> bool | None:
    """True: this process now holds the flock; False: another does; None: flock is not supported here."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
            return None
        raise


def _holder(fd: int) -> dict:
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", "replace")
        found = json.loads(text) if text.strip() else {}
        return found if isinstance(found, dict) else {}
    except (OSError, ValueError):
        return {}


def _stale(holder: dict) -> bool:
    """Without flock: the holder is a process of this host that no longer exists (or there is none)."""
    if not holder:
        return True
    if holder.get("host") != socket.gethostname():
        return False
    try:
        os.kill(int(holder["pid"]), 0)
    except ProcessLookupError:
        return True
    except (PermissionError, KeyError, ValueError, TypeError):
        return False
    return False


def _me(what: str) -> dict:
    return {"pid": os.getpid(), "host": socket.gethostname(), "what": what,
            "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds")}


def clean_temporaries(directory: str | pathlib.Path, names=None) -> list[pathlib.Path]:
    """Remove the temporary files (``.NAME.tmpPID``) that writers killed midway left in ``directory``:
    those whose process no longer exists on this host (a live one may still be writing); ``names``: only
    those of these file names (in a directory that is not petroll's own). Returns them."""
    directory = pathlib.Path(directory)
    removed = []
    with contextlib.suppress(OSError):
        for path in directory.iterdir():
            match = _TEMPORARY.match(path.name)
            if names is not None and (match is None or match.group(1) not in names):
                continue
            if match and path.is_file() and _stale({"pid": match.group(2), "host": socket.gethostname()}):
                with contextlib.suppress(OSError):
                    path.unlink()
                    removed.append(path)
    return removed
