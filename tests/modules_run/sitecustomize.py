"""Which modules of petroll ran code, in the test process and in every process it starts (`make check`).

Python imports ``sitecustomize`` at start-up from its path: scripts/test.sh puts this directory on
PYTHONPATH and names a directory in PETROLL_MODULES_RUN, so every Python of the run (pytest, the
``petroll`` commands it starts, mpirun's ranks, the docs' blocks, the peer solvers) loads this file. Once
the process imports petroll (from the start in a script of the package run by its path), a trace
function (sys.settrace, threading.settrace; no line events) notes each file whose code starts running:
``F FILE`` when one of its functions is called, ``M FILE`` when the module itself runs (its import).
Each note is one line appended at once to PETROLL_MODULES_RUN/PID (os.write on a descriptor opened at
start-up, O_APPEND), so a process killed by SIGKILL has said what it ran before, and a file system a test
fills or makes read-only does not stop it (the descriptor is open; a failed write is tried again at the
next note). tests/conftest.py reads the notes at the end of the session. Nothing is printed, nothing of
the process is changed but its trace function; without PETROLL_MODULES_RUN this file does nothing.
Debian's own sitecustomize (apport's hook) is not loaded in such a process.
"""

import os
import sys

COMPREHENSIONS = {"<listcomp>", "<dictcomp>", "<setcomp>", "<genexpr>"}  # run as part of their caller
CO_OPTIMIZED = 0x0001  # a function's code (a module's or class body's is not)


def _install(directory: str) -> None:
    try:
        fd = os.open(os.path.join(directory, str(os.getpid())), os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    except OSError:
        return
    state = {"pid": os.getpid(), "fd": fd}
    noted: set = set()  # (kind, file) already written
    pending: list = []  # notes not yet written (a write failed)

    def note(kind: str, filename: str) -> None:
        if os.getpid() != state["pid"]:  # a forked child: its own file, everything it runs noted again
            try:
                state["fd"] = os.open(os.path.join(directory, str(os.getpid())),
                                      os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
            except OSError:
                pass
            state["pid"] = os.getpid()
            noted.clear()
            done.clear()
        noted.add((kind, filename))
        pending.append(f"{kind} {filename}\n")
        try:
            os.write(state["fd"], "".join(pending).encode())
            pending.clear()
        except OSError:
            pass

    done: set = set()  # files with nothing more to note: not petroll's, or both notes written

    def trace(frame, event, arg):
        try:
            code = frame.f_code
            filename = code.co_filename
            if filename in done:
                return None
            if "petroll" not in filename:
                done.add(filename)
            elif code.co_name not in COMPREHENSIONS:
                kind = "F" if code.co_flags & CO_OPTIMIZED else "M"
                if (kind, filename) not in noted:
                    note(kind, filename)
                    if ("F", filename) in noted and ("M", filename) in noted:
                        done.add(filename)
        except BaseException:  # noqa: BLE001 (a trace function that raises is switched off by Python)
            pass
        return None

    def rearm() -> None:
        """Tracing again where it was switched off: by a RecursionError on the way into the trace function
        (a test of deep nesting) or by code that sets its own (tests/conftest.py calls this before each
        test)."""
        if "petroll" in sys.modules and sys.gettrace() is not trace:
            sys.settrace(trace)

    global petroll_rearm
    petroll_rearm = rearm

    def start() -> None:
        import threading

        threading.settrace(trace)
        sys.settrace(trace)

    class Finder:
        """On the first import of petroll (or a module of it): starts tracing, then steps aside."""

        @staticmethod
        def find_spec(name, path=None, target=None):
            if name == "petroll" or name.startswith("petroll."):
                sys.meta_path.remove(Finder)
                start()
            return None

    if "/petroll/" in (sys.argv[0] if sys.argv else ""):  # a script of the package (the peer solvers)
        start()
    else:
        sys.meta_path.insert(0, Finder)


if os.environ.get("PETROLL_MODULES_RUN"):
    _install(os.environ["PETROLL_MODULES_RUN"])
