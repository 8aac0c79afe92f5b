"""``petroll launch COMMAND...``: run an MPI launch line so that SIGTERM and SIGINT reach the ranks, and
its exit status is theirs (143, 130) (docs/cluster.md).

Open MPI's ``mpirun`` ends the job when it is itself signalled: it passes SIGTERM to the ranks whatever
the signal was, and exits with status 1 (measured with Open MPI 4.1), so a job script cannot tell a run
stopped by its time limit from a failure. Launched here instead, the command runs in a session of its own
(a terminal's Ctrl-C reaches only this process), and each SIGTERM or SIGINT is passed, as itself, to the
MPI ranks among the command's children on this node (the processes that carry an MPI rank in their
environment; petroll's ranks agree on a signal after every step, so one rank is enough), or to the
command itself when it has none. The ranks write their checkpoint and exit with 128 + the signal number,
which ``mpirun`` returns, and so does this. Linux only (it reads /proc).
"""

from __future__ import annotations

import os
import pathlib
import signal
import subprocess
import sys

RANK_VARIABLES = (b"OMPI_COMM_WORLD_RANK=", b"PMIX_RANK=", b"PMI_RANK=")
"""Environment entries that mark an MPI rank (Open MPI, PMIx, MPICH/Hydra)."""


def ranks_of(pid: int) -> list[int]:
    """The child processes of ``pid`` that are MPI ranks (this node only)."""
    found = []
    for entry in pathlib.Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            if int(stat[stat.rindex(")") + 2 :].split()[1]) != pid:  # the parent's PID, after the name
                continue
            environ = (entry / "environ").read_bytes().split(b"\0")
        except (OSError, ValueError, IndexError):
            continue
        if any(item.startswith(RANK_VARIABLES) for item in environ):
            found.append(int(entry.name))
    return found


def launch(command: list[str]) -> int:
    """Run ``command`` (e.g. ``mpirun -n 4 petroll run ...``) to its end, passing SIGTERM and SIGINT to its
    ranks; its exit status (128 + N if a signal N ended it)."""
    if not command:
        print("petroll: error: petroll launch needs a command, e.g. petroll launch mpirun -n 4 petroll run "
              "scene.toml", file=sys.stderr)
        return 2
    try:
        child = subprocess.Popen(command, start_new_session=True)
    except OSError as exc:
        print(f"petroll: error: {command[0]}: cannot be started ({exc.strerror or exc})", file=sys.stderr)
        return 2

    def forward(signum, frame):
        targets = ranks_of(child.pid) or [child.pid]
        for pid in targets:
            try:
                os.kill(pid, signum)
            except ProcessLookupError:
                pass

    previous = {s: signal.signal(s, forward) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        status = child.wait()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    return 128 - status if status < 0 else status
