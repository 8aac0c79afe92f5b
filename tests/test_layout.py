"""The package's rooms keep their rules (each package's __init__ states them): read from the source with
ast, every import counted, including those inside functions."""

import ast
import functools
import pathlib
import subprocess
import sys

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "petroll"
FACES = ("petroll.driver", "petroll.cli", "petroll.cli_parser", "petroll.plot", "petroll.launch")

FORBIDDEN = {
    "petroll.records": ("petroll.model", "petroll.solver", "petroll.io", "petroll.studies", "petroll.bench",
                        *FACES, "petsc4py", "mpi4py"),
    "petroll.model": ("petroll.solver", "petroll.io", "petroll.studies", "petroll.bench", *FACES, "petsc4py",
                      "mpi4py"),
    "petroll.solver": ("petroll.io", "petroll.studies", "petroll.bench", *FACES),
    "petroll.io": ("petroll.studies", "petroll.bench", *FACES),
    "petroll.studies": ("petroll.bench", "petroll.cli", "petroll.cli_parser"),
    # the one workflow a face runs (petroll.run(..., estimate_error=True)): built on Simulation, not on run
    "petroll.studies.estimate": FACES,
    "petroll.bench": ("petroll.cli", "petroll.cli_parser"),
}

IO_FROM_SOLVER = ("petroll.solver.partition",)
"""The solver's modules io may import: how a field's rows are split over the ranks (io writes and reads each
rank's rows). The step records io stores are petroll.records; a checkpoint restores a Simulation through
its attributes."""


@functools.cache
def sources() -> tuple[tuple[pathlib.Path, str, tuple[ast.AST, ...]], ...]:
    """Every module of petroll (sorted by path): its path, its text and every node of its tree (``ast.walk``'s
    order), read and parsed once for the rules below, which only read them."""
    return tuple((path, text, tuple(ast.walk(ast.parse(text))))
                 for path in sorted(PACKAGE.rglob("*.py")) for text in [path.read_text(encoding="utf-8")])


def module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports() -> dict[str, set[str]]:
    """Every module of petroll and the modules it imports (absolute names, anywhere in the file)."""
    graph = {}
    for path, _, nodes in sources():
        names = set()
        for node in nodes:
            if isinstance(node, ast.Import):
                names.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names.add(node.module)
                names.update(f"{node.module}.{alias.name}" for alias in node.names)
        graph[module_name(path)] = names
    return graph


def within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def test_no_room_imports_what_its_rules_forbid():
    broken = [(module, name) for module, names in imports().items() for room, banned in FORBIDDEN.items()
              if within(module, room) for name in names if any(within(name, b) for b in banned)]
    assert not broken, broken


def test_io_imports_nothing_of_the_solver_but_its_partition():
    graph = imports()
    broken = sorted((module, name) for module, names in graph.items() if within(module, "petroll.io")
                    for name in names if within(name, "petroll.solver")
                    and not any(within(name, allowed) for allowed in IO_FROM_SOLVER))
    assert not broken, broken


def test_only_the_command_line_imports_the_benchmarks():
    importers = {module for module, names in imports().items() if not within(module, "petroll.bench")
                 and any(within(name, "petroll.bench") for name in names)}
    assert importers == {"petroll.cli"}, importers


def test_the_install_holds_every_package_and_nothing_of_the_checkout_s_tools():
    """pyproject.toml lists every folder of petroll/ with an __init__.py (and the scenes): an install holds
    every room; the peers' scripts (scripts/peers/) and the fault injection (tests/kills.py) are no package
    of it."""
    import tomllib

    listed = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    folders = {module_name(path) for path in PACKAGE.rglob("__init__.py")}
    assert set(listed) == folders | {"petroll.scenes"}, set(listed) ^ (folders | {"petroll.scenes"})
    assert not list(PACKAGE.rglob("solve_*.py")) and not list(PACKAGE.rglob("kills.py"))


def test_no_import_circles():
    graph = imports()
    modules = set(graph)
    edges = {m: {n for n in graph[m] if n in modules and n != m and not within(m, n)} for m in modules}
    state: dict[str, int] = {}

    def visit(m, trail):
        state[m] = 1
        for n in sorted(edges[m]):
            if state.get(n) == 1:
                raise AssertionError("import circle: " + " -> ".join([*trail, m, n]))
            if n not in state:
                visit(n, [*trail, m])
        state[m] = 2

    for m in sorted(modules):
        if m not in state:
            visit(m, [])


@pytest.mark.serial
def test_importing_petroll_and_its_model_starts_neither_mpi_nor_petsc():
    code = ("import sys, petroll, petroll.model.scene, petroll.model.materials, petroll.model.bodies; "
            "scene = petroll.load_scene(sys.argv[1]); "
            "print(sorted(m for m in ('mpi4py.MPI', 'petsc4py.PETSc') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code, str(PACKAGE.parent / "runs" / "sphere.toml")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


@pytest.mark.serial
@pytest.mark.parametrize("launched", [False, True])
def test_a_process_no_launcher_started_starts_open_mpi_without_its_helper_daemon(launched):
    """petroll.solver, imported before MPI starts, starts Open MPI as an isolated singleton with the ob1
    messaging layer unless a launcher (mpirun: OMPI_COMM_WORLD_SIZE) started the process; the process then
    runs MPI (one rank) as before, and the processes it starts inherit none of these settings."""
    import os

    from petroll.solver import SINGLETON

    env = {k: v for k, v in os.environ.items()
           if k not in ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", *SINGLETON)}
    if launched:
        env["OMPI_COMM_WORLD_SIZE"] = "1"
    code = (f"import os, petroll.solver as s; print(s.MPI_SETTINGS == ({{}} if {launched} else s.SINGLETON), "
            f"*(k in os.environ for k in {tuple(SINGLETON)!r}))")
    if not launched:
        code += "; from mpi4py import MPI; w = MPI.COMM_WORLD; print(MPI.Is_initialized(), w.allreduce(w.size))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "False", "False"] + ([] if launched else ["True", "1"])


def private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def test_no_private_name_is_imported_across_modules():
    """No ``from petroll.x import _y`` (absolute or relative) and no ``x._y`` where ``x`` is an imported
    petroll module: a name used by another module is public."""
    used = []
    for path, _, nodes in sources():
        me = module_name(path)
        package = me if path.name == "__init__.py" else me.rpartition(".")[0]
        modules = {}  # local name -> petroll module it is bound to
        for node in nodes:
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if within(alias.name, "petroll"):
                        modules[alias.asname or alias.name.partition(".")[0]] = alias.asname and alias.name
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join([*package.split(".")[: len(package.split(".")) - node.level + 1],
                                     *([base] if base else [])])
                if not within(base, "petroll"):
                    continue
                for alias in node.names:
                    if private(alias.name) and base != me:
                        used.append(f"{me}: from {base} import {alias.name}")
                    modules[alias.asname or alias.name] = f"{base}.{alias.name}"
        for node in nodes:
            if isinstance(node, ast.Attribute) and private(node.attr):
                chain, value = [], node.value
                while isinstance(value, ast.Attribute):
                    chain.insert(0, value.attr)
                    value = value.value
                if isinstance(value, ast.Name) and value.id in modules:
                    used.append(f"{me}: {'.'.join([value.id, *chain, node.attr])}")
    assert not used, used


FUNCTION_LINES, MODULE_LINES = 80, 600
"""Rooms a reader can take in: no function longer, no module longer, but for the exceptions below."""

LONG_MODULES: dict[str, str] = {}
LONG_FUNCTIONS = {
    ("petroll/solver/pk.py", "solve"): "the Polonsky-Keer iteration: one loop whose steps (projection, "
                                       "re-entry, conjugate direction, the load's constraint) share a dozen "
                                       "locals",
}


def test_no_function_over_80_lines_and_no_module_over_600_beyond_the_listed_exceptions():
    """Counted from the source (a function from its def to its last line, nested ones too); an exception
    that no longer needs its place in the lists fails too, so that the lists stay true."""
    modules, functions = {}, {}
    for path, text, nodes in sources():
        name = str(path.relative_to(PACKAGE.parent))
        modules[name] = len(text.splitlines())
        for node in nodes:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions[name, node.name] = max(functions.get((name, node.name), 0),
                                                 node.end_lineno - node.lineno + 1)
    long_modules = {m for m, n in modules.items() if n > MODULE_LINES}
    long_functions = {f for f, n in functions.items() if n > FUNCTION_LINES}
    assert long_modules <= set(LONG_MODULES), {m: modules[m] for m in long_modules - set(LONG_MODULES)}
    unlisted = long_functions - set(LONG_FUNCTIONS)
    assert not unlisted, {f: functions[f] for f in unlisted}
    assert not set(LONG_MODULES) - long_modules, "listed but no longer long: remove from LONG_MODULES"
    assert not set(LONG_FUNCTIONS) - long_functions, "listed but no longer long: remove from LONG_FUNCTIONS"


TOPOLOGY_READERS = ("petroll/model/topology.py",)
"""The modules that read a grid's ``periodic`` values: its topology (petroll.model.topology, which owns what
differs between a windowed half-space, periodic grids and line contact)."""


def test_only_the_topology_reads_whether_a_grid_repeats():
    """No ``x.periodic`` attribute is read outside the grid's topology (a module's function of that
    name, ``bench_rough.periodic``, is not one): what differs between topologies is a method or property
    of the topology (``grid.topology``), not a test of the flag."""
    readers = set()
    for path, _, nodes in sources():
        imported = {alias.asname or alias.name for node in nodes
                    if isinstance(node, (ast.Import, ast.ImportFrom)) for alias in node.names}
        if any(isinstance(node, ast.Attribute) and node.attr == "periodic"
               and not (isinstance(node.value, ast.Name) and node.value.id in imported)
               for node in nodes):
            readers.add(str(path.relative_to(PACKAGE.parent)))
    assert set(readers) <= set(TOPOLOGY_READERS), sorted(set(readers) - set(TOPOLOGY_READERS))
    assert set(readers) == set(TOPOLOGY_READERS), "a listed reader no longer reads it: update the list"


def test_the_time_mode_is_an_enum_never_compared_with_a_string():
    """[time] mode is a petroll.model.clock.TimeMode: no ``x.mode == "steady"`` (or any string) anywhere, and
    the time loop runs a steady solve through the protocol of petroll.solver.steady_state without naming
    which (no rolling or sliding class in petroll/solver/simulation.py)."""
    compared = []
    for path, _, nodes in sources():
        for node in nodes:
            if isinstance(node, ast.Compare):
                sides = [node.left, *node.comparators]
                if (any(isinstance(s, ast.Attribute) and s.attr == "mode" for s in sides)
                        and any(isinstance(s, ast.Constant) and isinstance(s.value, str) for s in sides)):
                    compared.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}")
    assert not compared, compared
    loop = imports()["petroll.solver.simulation"]
    assert not {n for n in loop if within(n, "petroll.solver.steady") or within(n, "petroll.solver.sliding")}
    assert "petroll.solver.steady_state" in loop


PETSC_IMPORTERS = {
    "petroll.solver.petsc": "the adapter: every TAO, KSP, shell matrix, PC and vector petroll makes",
    "petroll.solver.pk": "the Polonsky-Keer conjugate gradient is a TAO type itself, on PETSc vectors",
    "petroll.cli": "petsc4py.init with the command line's PETSc options, before anything starts PETSc",
    "petroll.bench.memory": "petsc4py.init in the benchmark's child processes",
    "petroll.bench.mpi": "petsc4py.init in the benchmark's child processes",
    "petroll.bench.rough": "petsc4py.init in the benchmark's child processes",
    "petroll.bench.friction": "compares TAO's types on friction's QP, as `bench tao` does the contact's",
}
"""The modules that import petsc4py, and why; the contact, sliding and tangential numerics are numpy."""


def test_petsc_is_imported_only_by_the_adapter_and_the_listed_modules():
    importers = {module for module, names in imports().items() if any(within(n, "petsc4py") for n in names)}
    assert importers <= set(PETSC_IMPORTERS), sorted(importers - set(PETSC_IMPORTERS))
    assert importers == set(PETSC_IMPORTERS), "listed but no longer importing petsc4py: update the list"
