"""Where big blocks come from (petroll.solver.allocation): glibc maps them while a run whose QP covers the
whole grid goes, and the heap is as before once it ends. The oracle is the kernel's: an array between the
start of the process's ``[heap]`` (/proc/self/maps) and its program break (``sbrk(0)``) came from the brk
heap, one elsewhere was mapped.

Each case runs in a child process that has loaded PETSc as petroll does (its libraries set the allocator
at load), so the heap is that of a petroll process, not the test runner's."""

import json
import subprocess
import sys

import pytest

CHILD = r"""
import ctypes, json, sys, warnings
import numpy as np
import petsc4py
petsc4py.init([])
import petroll
from petroll.model.scene import parse_scene
from petroll.solver.allocation import BLOCK, LargeBlocksMapped

libc = ctypes.CDLL(None)
libc.sbrk.restype, libc.sbrk.argtypes = ctypes.c_void_p, [ctypes.c_ssize_t]

def from_heap():  # a fresh array of 4 BLOCKs, not touched: does it lie in the brk heap?
    block = np.empty(4 * BLOCK // 8)
    for line in open("/proc/self/maps"):  # the heap's first part (numpy's madvise may split it)
        if line.rstrip().endswith("[heap]"):
            return int(line.split("-")[0], 16) <= block.ctypes.data < libc.sbrk(0)
    return False

seen = {"before": from_heap()}
with LargeBlocksMapped(True) as policy:
    seen["inside"], seen["switched"], seen["reason"] = from_heap(), policy.switched, policy.reason
seen["after"] = from_heap()
with LargeBlocksMapped(False) as policy:
    seen["off"], seen["off_reason"] = from_heap(), policy.reason
for name, periodic in (("periodic", True), ("windowed", False)):
    raw = {"grid": {"nx": 16, "ny": 16, "x": [-1e-3, 1e-3], "y": [-1e-3, 1e-3], "periodic": periodic,
                    "allow_coarse": True},
           "material": {"model": "elastic", "E": 1e7, "nu": 0.5},
           "body": {"shape": "sphere", "radius": 5e-3}, "motion": {"load": 1e-3}}
    during = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        petroll.run(parse_scene(raw), out=sys.argv[1] + "/" + name, on_step=lambda r: during.append(from_heap()))
    seen[name], seen[name + "_after"] = during, from_heap()
print(json.dumps(seen))
"""


@pytest.mark.serial
def test_big_blocks_are_mapped_during_a_whole_grid_run_only(tmp_path):
    """In a process with PETSc loaded: inside the policy a block of 4 BLOCKs is mapped, and after it the
    heap serves it as before (Debian's PETSc turns glibc's mapping off: the policy turned it on and off
    again; where mapping was on, it changed nothing and says so). Inactive, it changes nothing and says
    why. A periodic scene's step runs with big blocks mapped, a windowed scene's from the heap as before,
    and after either run the heap is as before."""
    done = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    before = seen["before"]
    assert seen["inside"] is False
    assert seen["switched"] is before and (seen["reason"] is None) is before
    assert seen["after"] is before and seen["off"] is before
    assert seen["off_reason"] == "the run's QP is posed on windows"
    assert seen["periodic"] == [False] and seen["periodic_after"] is before
    assert seen["windowed"] == [before] and seen["windowed_after"] is before
