#!/usr/bin/env python3
"""Same results: every shipped scene and a set of variants run into a folder, and two such folders compared.

    .venv/bin/python scripts/same-results.py run /tmp/same-before                  # this checkout's petroll
    .venv/bin/python scripts/same-results.py run /tmp/same-old --petroll /work/main/.venv/bin/petroll
    .venv/bin/python scripts/same-results.py compare /tmp/same-before /tmp/same-after

``run`` writes one run directory per case (the scenes of runs/ as shipped, then variants on small grids:
periodic along X, Y and both, transient and steady; line contact, periodic and steady; steady rolling
along Y and under load control; a layer in 3-D and steady; friction, transient; other TAO types and
integrators; a restart from a checkpoint; the error estimate; stresses; two ranks), with the scene file each ran and its
output. ``compare`` reads every HDF5 file of every case in both folders and compares every dataset and
attribute bitwise, except the wall-clock values and the run's identity (``IGNORED``) and the places
listed in ``TOLERATED`` (within 1e-12 relative, each with its reason); text files (.xdmf, .csv) are
compared whole. Exit status 1 on any difference, naming each. The reshaping of issue 36 was checked
with it (docs/design.md).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import shutil
import subprocess
import sys
import time
import tomllib

import h5py
import numpy as np
import tomli_w

ROOT = pathlib.Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs"

IGNORED_ATTRIBUTES = {"run_id", "scene_file", "created", "wall_s", "run_wall_s"}
"""Attributes that name the run or time it, not its numbers (on any group or dataset of any file)."""
IGNORED = {"series/solve_time", "series/solve_time@sha256", "@sha256"}
"""Wall-clock times, and the digests over them (a checkpoint's digest of the whole file: every value it
covers but the times is compared)."""

TOLERATED: dict[tuple[str, str], str] = {}
"""(case, file:path) -> why its values may differ within 1e-12 relative (an operation's order changed)."""
RELATIVE = 1e-12

SPHERE_SMALL = {"grid.nx": 64, "grid.ny": 48, "grid.x": [-1.2e-3, 2.0e-3], "grid.y": [-1.2e-3, 1.2e-3],
                "time.distance": 0.6e-3, "time.steady": None, "output.every": 5}
"""runs/sphere.toml on 64 x 48 cells of 50 um over 0.6 mm of rolling (also a periodic cell the sphere fits
in)."""

ROUGH_SMALL = {"grid.nx": 64, "grid.ny": 64, "body.cutoff": 2.5e-4, "time.steps_per_cell": 2}
"""runs/rough-rubber.toml on 64^2 cells (its short cut-off 4 cells again)."""

CASES: dict[str, tuple[str, dict, dict]] = {
    # name: (scene of runs/, changes (key: value; None removes it), how: ranks, restart, estimate, stress)
    "periodic-xy": ("sphere.toml", {**SPHERE_SMALL, "grid.periodic": True}, {}),
    "periodic-x": ("sphere.toml", {**SPHERE_SMALL, "grid.periodic": ["x"]}, {}),
    "periodic-y": ("sphere.toml", {**SPHERE_SMALL, "grid.periodic": ["y"]}, {}),
    "periodic-xy-load": ("sphere.toml", {**SPHERE_SMALL, "grid.periodic": True, "motion.penetration": None,
                                         "motion.load": 0.05}, {}),
    "sliding-xy": ("rough-rubber.toml", ROUGH_SMALL, {}),
    "sliding-xy-diagonal": ("rough-rubber.toml", {**ROUGH_SMALL, "motion.velocity": [0.006, 0.008]}, {}),
    "sliding-x": ("master-curve.toml", {"grid.periodic": ["x"], "grid.nx": 48,
                                        "grid.x": [-1.2e-3, 1.2e-3]}, {}),
    "sliding-y": ("master-curve.toml", {"grid.periodic": ["y"], "grid.ny": 48, "grid.y": [-1.2e-3, 1.2e-3],
                                        "motion.velocity": [0.0, 0.01]}, {}),
    "line-periodic": ("roller-2d.toml", {"grid.periodic": True, "grid.nx": 96, "grid.x": [-2.4e-3, 2.4e-3],
                                         "time.distance": 1.0e-3, "time.steady": None}, {}),
    "line-steady": ("roller-2d.toml", {"time.mode": "steady", "time.distance": None, "time.steady": None,
                                       "time.steps_per_cell": None, "grid.nx": 96,
                                       "grid.x": [-2.4e-3, 2.4e-3], "output.every": None}, {}),
    "line-sliding": ("roller-2d.toml", {"time.mode": "steady", "time.distance": None, "time.steady": None,
                                        "time.steps_per_cell": None, "grid.nx": 96, "grid.periodic": True,
                                        "grid.x": [-2.4e-3, 2.4e-3], "output.every": None}, {}),
    "steady-y": ("master-curve.toml", {"motion.velocity": [0.0, 0.02]}, {}),
    "steady-load": ("master-curve.toml", {"motion.penetration": None, "motion.load": 0.05}, {}),
    "steady-layer": ("master-curve.toml", {"material.layer": {"thickness": 1.0e-3, "base": "bonded"}}, {}),
    "layer-3d": ("sphere.toml", {**SPHERE_SMALL, "material.layer": {"thickness": 0.6e-3, "base": "bonded"}},
                 {}),
    "layer-line-slip": ("conveyor-idler.toml", {"material.layer": {"thickness": 6.0e-3,
                                                                   "base": "frictionless"},
                                                "grid.nx": 150, "time.distance": 10.0e-3}, {}),
    "tao-tron": ("hertz.toml", {"solver.tao_type": "tron"}, {}),
    "tao-blmvm": ("hertz.toml", {"solver.tao_type": "blmvm"}, {}),
    "tao-gpcg": ("sphere.toml", {**SPHERE_SMALL, "solver.tao_type": "gpcg"}, {}),
    "tao-bncg-load": ("sphere.toml", {**SPHERE_SMALL, "solver.tao_type": "bncg", "motion.penetration": None,
                                      "motion.load": 0.04}, {}),
    "exponential": ("sphere.toml", {**SPHERE_SMALL, "solver.integrator": "exponential"}, {}),
    "paper": ("sphere.toml", {**SPHERE_SMALL, "solver.integrator": "paper"}, {}),
    "friction-transient": ("traction-curve.toml", {"time.mode": None, "time.steps_per_cell": 1,
                                                   "time.distance": 0.3e-3, "grid.nx": 64,
                                                   "grid.x": [-0.75e-3, 1.25e-3]}, {}),
    "restart": ("sphere.toml", {"output.checkpoint_every": 10, "output.keep": 10}, {"restart": 20}),
    "estimate": ("hertz.toml", {"grid.nx": 32, "grid.ny": 32}, {"estimate": True}),
    "stress": ("hertz.toml", {"output.fields": ["pressure", "displacement", "gap"]}, {"stress": True}),
    "two-ranks": ("sphere.toml", {}, {"ranks": 2}),
    "two-ranks-periodic": ("sphere.toml", {**SPHERE_SMALL, "grid.periodic": True}, {"ranks": 2}),
    "two-ranks-steady": ("master-curve.toml", {}, {"ranks": 2}),
    "two-ranks-sliding": ("rough-rubber.toml", ROUGH_SMALL, {"ranks": 2}),
}


def changed(raw: dict, changes: dict) -> dict:
    """The scene dict with ``section.key`` values set (None: removed)."""
    for key, value in changes.items():
        section, name = key.split(".")
        table = raw.setdefault(section, {})
        if value is None:
            table.pop(name, None)
        else:
            table[name] = value
    return raw


def call(command: list[str], log: pathlib.Path) -> None:
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    with open(log, "a") as out:
        out.write("$ " + " ".join(command) + "\n")
        out.flush()
        done = subprocess.run(command, stdout=out, stderr=subprocess.STDOUT, env=env, cwd=ROOT)
    if done.returncode:
        sys.exit(f"same-results: {' '.join(command)} failed (status {done.returncode}); see {log}")


def run_case(petroll: str, folder: pathlib.Path, name: str, scene: str, changes: dict, how: dict) -> None:
    case = folder / name
    case.mkdir(parents=True)
    raw = changed(tomllib.loads((RUNS / scene).read_text()), changes)
    raw.setdefault("output", {})["dir"] = str(case / "run")
    for key in ("file",):  # relative inputs (a DMA table, a height map) from runs/
        if key in raw.get("material", {}):
            raw["material"][key] = str(RUNS / raw["material"][key])
    path = case / "scene.toml"
    path.write_text(tomli_w.dumps(raw))
    log = case / "output.txt"
    launch = ["mpirun", "-n", str(how["ranks"]), "--oversubscribe"] if how.get("ranks") else []
    call([*launch, petroll, "run", str(path), "--out", str(case / "run"), "--quiet",
          *(["--estimate-error"] if how.get("estimate") else [])], log)
    if how.get("restart"):
        checkpoint = case / "run" / "checkpoints" / f"step-{how['restart']:08d}.h5"
        call([petroll, "restart", str(checkpoint), "--out", str(case / "restarted"), "--quiet"], log)
    if how.get("stress"):
        call([petroll, "stress", str(case / "run")], log)


def run(folder: pathlib.Path, petroll: str, only: list[str]) -> None:
    if folder.exists():
        sys.exit(f"same-results: {folder} exists: give a new folder")
    cases = {f"shipped-{p.stem}": (p.name, {}, {}) for p in sorted(RUNS.glob("*.toml"))} | CASES
    for name, (scene, changes, how) in cases.items():
        if only and name not in only:
            continue
        start = time.perf_counter()
        run_case(petroll, folder, name, scene, changes, how)
        print(f"{name:<24} {time.perf_counter() - start:6.1f} s", flush=True)


def entries(path: pathlib.Path, folder: pathlib.Path) -> dict[str, object]:
    """Every dataset (as an array) and attribute (as its value) of an HDF5 file, by name: "group/name" for
    a dataset, "group/name@attribute" for an attribute (the file's own: "@attribute"); ``folder`` in a
    text (the scene's output directory, a source's path) written as "FOLDER"."""
    found: dict[str, object] = {}

    def text(value):
        if isinstance(value, np.ndarray) and value.dtype.kind == "O":
            return np.array([text(v) for v in value.ravel()], dtype=object).reshape(value.shape)
        if isinstance(value, bytes):
            return value.replace(str(folder).encode(), b"FOLDER")
        return value.replace(str(folder), "FOLDER") if isinstance(value, str) else value

    def add(prefix, attrs):
        found.update({f"{prefix}@{k}": text(v) for k, v in attrs.items() if k not in IGNORED_ATTRIBUTES})

    with h5py.File(path, "r") as f:
        add("", f.attrs)

        def visit(name, obj):
            add(name, obj.attrs)
            if isinstance(obj, h5py.Dataset):
                found[name] = obj[()]

        f.visititems(visit)
    return {k: v for k, v in found.items() if k not in IGNORED}


def same(a, b) -> bool:
    """Bitwise equality: the same type, shape and bytes (NaNs equal where their bits are)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype.kind == "O":
        return all(same(x, y) for x, y in zip(a.ravel(), b.ravel()))
    return a.tobytes() == b.tobytes()


def within(a, b) -> float | None:
    """The largest relative difference of two float arrays of the same shape, or None if not floats."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype.kind != "f" or b.dtype.kind != "f":
        return None
    scale = np.maximum(np.abs(a), np.abs(b))
    return float(np.max(np.where(scale > 0, np.abs(a - b) / np.where(scale > 0, scale, 1), 0), initial=0))


def compare(old: pathlib.Path, new: pathlib.Path) -> int:
    problems, tolerated, files, values = [], [], 0, 0
    cases = sorted({p.name for folder in (old, new) for p in folder.iterdir() if p.is_dir()})
    for case in cases:
        names = sorted({p.relative_to(old / case) for p in (old / case).rglob("*") if p.is_file()}
                       | {p.relative_to(new / case) for p in (new / case).rglob("*") if p.is_file()})
        for name in names:
            if name.suffix not in (".h5", ".xdmf", ".csv") or name.name.startswith("."):
                continue
            a, b = old / case / name, new / case / name
            if not (a.exists() and b.exists()):
                problems.append(f"{case}: {name} only in {'new' if b.exists() else 'old'}")
                continue
            files += 1
            if name.suffix != ".h5":
                if a.read_bytes().replace(bytes(old), b"F") != b.read_bytes().replace(bytes(new), b"F"):
                    problems.append(f"{case}: {name} differs")
                continue
            ea, eb = entries(a, old), entries(b, new)
            for key in sorted(set(ea) | set(eb)):
                where = f"{name}:{key}"
                if key not in ea or key not in eb:
                    problems.append(f"{case}: {where} only in {'new' if key in eb else 'old'}")
                    continue
                values += 1
                if same(ea[key], eb[key]):
                    continue
                gap = within(ea[key], eb[key])
                reason = next((why for (c, w), why in TOLERATED.items()
                               if c in (case, "*") and w in (where, f"*:{key}")), None)
                if reason and gap is not None and gap <= RELATIVE:
                    tolerated.append(f"{case}: {where}: {gap:.1e} relative ({reason})")
                else:
                    gap_text = "" if gap is None else f": {gap:.3e} relative"
                    problems.append(f"{case}: {where} differs{gap_text}")
    for line in tolerated:
        print("within 1e-12:", line)
    for line in problems:
        print("DIFFERS:", line)
    print(f"{len(cases)} cases, {files} files, {values} datasets and attributes: "
          f"{values - len(problems) - len(tolerated)} bitwise the same, {len(tolerated)} within 1e-12 "
          f"relative (listed), {len(problems)} different")
    return 1 if problems else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    verbs = parser.add_subparsers(dest="verb", required=True)
    r = verbs.add_parser("run", help="run every case into FOLDER (a new folder)")
    r.add_argument("folder", type=pathlib.Path)
    r.add_argument("--petroll", default=str(ROOT / ".venv" / "bin" / "petroll"),
                   help="the petroll command to run (default: this checkout's .venv)")
    r.add_argument("--only", nargs="*", default=[], help="these cases only")
    c = verbs.add_parser("compare", help="compare two folders that run wrote")
    c.add_argument("old", type=pathlib.Path)
    c.add_argument("new", type=pathlib.Path)
    args = parser.parse_args()
    if args.verb == "run":
        if not shutil.which(args.petroll):
            sys.exit(f"same-results: --petroll {args.petroll}: not an executable")
        run(args.folder, args.petroll, args.only)
        return 0
    return compare(args.old, args.new)


if __name__ == "__main__":
    sys.exit(main())
