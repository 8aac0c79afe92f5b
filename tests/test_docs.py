"""Every documented command runs as written: the fenced ``sh``/``bash`` and ``python`` blocks of README.md and
docs/*.md are extracted and run, one document at a time, in order, in a temporary copy of the repository
(its ``.venv`` linked to this one), so a document cannot drift from the code. Links between documents and
cited sections ("formulation §7") must resolve.

Conventions (docs/contributing.md explains them with examples). A marker is an HTML comment on the line
just above a fence; readers do not see it:

- no marker: the block runs as written (``sh``/``bash`` with ``bash -euo pipefail``, ``python`` as a
  script); blocks of one document share one copy, so a block may use what an earlier one wrote;
  ``mpirun -n N`` lines run as written (Open MPI may run as root and oversubscribe).
- ``<!-- docs-test: long "TEXT" -> "SMALLER" ... -->``: a long block (a benchmark, a sweep) runs with each
  TEXT replaced by SMALLER, e.g. fewer sweep points; every TEXT must occur in the block.
- ``<!-- docs-test: output -->`` above a plain fence: what the block before it prints, checked against
  that block's output; ``...`` stands for any text within a line (a wall time).
- ``<!-- docs-test: pvpython -->`` above a ``python`` block: run with ParaView's ``pvpython``
  (``--force-offscreen-rendering``; scripts/setup-tests.sh installs it).
- ``<!-- docs-test: skip REASON -->``: not run, for a reason a reader can check (it needs Slurm, it is the
  test suite itself). Other languages (``toml``, ``text``, no language) are not run.
- ``<!-- docs-test: elsewhere -->`` above a shell block that repeats commands of other pages (README's
  overviews): each of its commands that a block of another document runs is not run here, the others
  are (with the replacements of a ``long`` list after the word, if any); at least one must be elsewhere.

A ``.venv/bin/python -m pytest`` line runs with ``--collect-only``: the suite runs those tests itself.
Each command (a shell line starting ``.venv/bin/``, ``mpirun`` or ``make``, compared as written and as run:
comments and spacing aside) runs once per document: a block repeating one that an earlier block ran (the
text showing a command again where it discusses it) runs without it, and so does a line repeating an
earlier line of its own block (a long line whose replacement is the quick line shown below it). Each
document is one test, serial (it starts processes); the whole takes a few minutes.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import re
import shlex
import shutil
import signal
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELL = {"sh", "bash"}
FENCE = re.compile(r"^(?:<!--\s*docs-test:(?P<marker>.*?)-->\n)?```(?P<lang>[\w-]*)[^\n]*\n(?P<body>.*?)^```",
                   re.M | re.S)
REPLACE = re.compile(r'"([^"]*)"\s*->\s*"([^"]*)"')
IGNORED = shutil.ignore_patterns(".git", ".venv", ".venv-peers", "results", "*.egg-info",
                                 ".pytest_cache", ".hypothesis", "build")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_btl_vader_single_copy_mechanism="none",
           OMPI_MCA_mpi_yield_when_idle="1", MPLBACKEND="Agg")


@dataclasses.dataclass
class Block:
    """One fenced block: its language, text, marker (the comment's text, "" without one) and line."""

    lang: str
    body: str
    marker: str
    line: int

    @property
    def kind(self) -> str:
        """run, long, output, skip or text (not run)."""
        word = self.marker.split()[0] if self.marker.strip() else ""
        if word in ("skip", "output", "long"):
            return word
        if word == "elsewhere":
            assert self.lang in SHELL, f"line {self.line}: an elsewhere marker above a {self.lang} block"
            return "long"
        if word == "pvpython":
            assert self.lang == "python", f"line {self.line}: a pvpython marker above a {self.lang} block"
            return "run"
        assert not word, f"line {self.line}: unknown docs-test marker {self.marker!r}"
        return "run" if self.lang in SHELL | {"python"} else "text"

    @property
    def elsewhere(self) -> bool:
        return self.marker.startswith("elsewhere")

    def lines(self) -> list[tuple[str, str]]:
        """Each line of the block as written and as run: with a long block's replacements made and, in a
        shell block, a ``.venv/bin/python -m pytest`` line (the suite's own tests, which it runs itself)
        collecting its tests, not running them (``--collect-only``)."""
        pairs = [(line, line) for line in self.body.splitlines(keepends=True)]
        for old, new in REPLACE.findall(self.marker):
            assert old in self.body and "\n" not in old, (
                f"line {self.line}: the long marker's {old!r} is not in a line of the block")
            pairs = [(written, run.replace(old, new)) for written, run in pairs]
        if self.lang in SHELL:
            pairs = [(written, re.sub(r"^(\s*\.venv/bin/python -m pytest)(?![^\n#]*--collect-only)",
                                      r"\1 --collect-only", run)) for written, run in pairs]
        return pairs

    def source(self, leave: frozenset = frozenset()) -> str:
        """The text to run: the lines as run, but those whose command (as written or as run, see
        ``command``) is in ``leave`` or, in a block whose lines are each a command (``commands``), was
        a command of an earlier line of the block (a line showing the quick form of the line above)."""
        text, leave = [], set(leave)
        each = bool(self.commands())
        for written, run in self.lines():
            names = {command(written), command(run)} - {None}
            if not names & leave:
                text.append(run)
            if each:
                leave |= names
        return "".join(text)

    def commands(self) -> set[str]:
        """The commands of a shell block that runs, as written and as run (see ``command``); none in a
        block with a here-document or a continued line (its lines are not each a command)."""
        if self.lang not in SHELL or self.kind not in ("run", "long") or any(
                mark in self.body for mark in ("<<", "\\\n")):
            return set()
        return {command(line) for pair in self.lines() for line in pair} - {None}


def command(line: str) -> str | None:
    """The command a shell line runs, compared as written (its words: comments and spacing aside), when it
    is one run once per document: it starts with ``.venv/bin/``, ``mpirun`` or ``make``; else None."""
    try:
        words = shlex.split(line, comments=True)
    except ValueError:
        return None
    if words and (words[0].startswith(".venv/bin/") or words[0] in ("mpirun", "make")):
        return " ".join(words)
    return None


def blocks(doc: pathlib.Path) -> list[Block]:
    text = doc.read_text(encoding="utf-8")
    return [Block(m["lang"], m["body"], (m["marker"] or "").strip(), text.count("\n", 0, m.start("lang")) + 1)
            for m in FENCE.finditer(text)]


def runnable(doc: pathlib.Path) -> bool:
    return any(block.kind in ("run", "long") for block in blocks(doc))


def _copy(tmp_path: pathlib.Path) -> pathlib.Path:
    """A copy of the repository without its outputs, its .venv a link to the one running the tests."""
    copy = tmp_path / "petroll"
    shutil.copytree(ROOT, copy, ignore=IGNORED, symlinks=True)
    (copy / ".venv").symlink_to(pathlib.Path(sys.prefix))
    return copy


def _run(block: Block, source: str, cwd: pathlib.Path, timeout: float) -> subprocess.CompletedProcess:
    if block.lang == "python":
        script = cwd.parent / "blocks" / f"line-{block.line}.py"  # not beside the copy: it would be imported
        script.parent.mkdir(exist_ok=True)
        script.write_text(source, encoding="utf-8")
        argv = [sys.executable, str(script)]
        if block.marker.startswith("pvpython"):
            argv = [shutil.which("pvpython") or "pvpython", "--force-offscreen-rendering", str(script)]
    else:
        argv = ["bash", "-euo", "pipefail", "-c", source]
    with subprocess.Popen(argv, cwd=cwd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          start_new_session=True) as process:
        try:
            out, err = process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)  # the block's children too
            out, err = process.communicate()
            err += f"\n(killed after {timeout:g} s)"
    return subprocess.CompletedProcess(argv, process.returncode, out, err)


def _matches(expected: str, output: str) -> bool:
    """Whether every line of ``expected`` occurs in ``output`` as a line, ``...`` matching any text."""
    lines = output.splitlines()
    for want in expected.strip().splitlines():
        pattern = re.compile(".*?".join(map(re.escape, want.strip().split("..."))))
        if not any(pattern.fullmatch(line.strip()) for line in lines):
            return False
    return True


def run_elsewhere(doc: pathlib.Path) -> frozenset:
    """The commands that blocks of documents other than ``doc`` run (elsewhere blocks not counted)."""
    return frozenset().union(*(block.commands() for other in DOCS if other != doc for block in blocks(other)
                               if not block.elsewhere))


def run_document(doc: pathlib.Path, tmp_path: pathlib.Path) -> pathlib.Path:
    """Run the blocks of ``doc`` in order in a copy of the repository under ``tmp_path`` (the conventions
    of this module's docstring); returns the copy, with what the blocks wrote (``results/...``)."""
    copy = _copy(tmp_path)
    previous = None
    ran = frozenset()  # the commands this document's blocks ran
    elsewhere = run_elsewhere(doc)
    for block in blocks(doc):
        where = f"{doc.relative_to(ROOT)}:{block.line}"
        if block.kind == "skip":
            assert len(block.marker.split()) > 2, f"{where}: a skipped block says why"
        elif block.kind == "output":
            assert previous is not None, f"{where}: an output block follows a block that runs"
            assert _matches(block.body, previous.stdout), (
                f"{where}: the block above printed\n{previous.stdout}\nnot\n{block.body}")
        elif block.kind in ("run", "long"):
            leave = ran | (elsewhere if block.elsewhere else frozenset())
            if block.elsewhere:
                assert block.commands() & elsewhere, f"{where}: no command of this block runs elsewhere"
            source = block.source(leave)
            ran |= block.commands()
            if not [line for line in source.splitlines() if line.strip() and not line.lstrip().startswith("#")]:
                previous = None  # each of its commands ran before: nothing to run, no output to check
                continue
            previous = _run(block, source, copy, timeout=300)
            assert previous.returncode == 0, (
                f"{where} failed (exit {previous.returncode}):\n{source}\n"
                f"stdout:\n{previous.stdout[-3000:]}\nstderr:\n{previous.stderr[-3000:]}")
    return copy


_RAN: dict[pathlib.Path, pathlib.Path | AssertionError] = {}


def document_run(doc: pathlib.Path, tmp_path_factory) -> pathlib.Path:
    """``run_document`` once a session: the copy it left, or its failure again. Tests that check what a
    document's block writes (tests/test_bench.py: ``petroll bench ... --quick``) read it there instead of
    running the same command a second time."""
    if doc not in _RAN:
        try:
            _RAN[doc] = run_document(doc, tmp_path_factory.mktemp(doc.stem))
        except AssertionError as failure:
            _RAN[doc] = failure
            raise
    if isinstance(_RAN[doc], AssertionError):
        raise AssertionError(f"{doc.relative_to(ROOT)}'s blocks failed") from _RAN[doc]
    return _RAN[doc]


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.parametrize("doc", [d for d in DOCS if runnable(d)], ids=lambda d: str(d.relative_to(ROOT)))
def test_every_block_runs_as_written(doc, tmp_path_factory):
    document_run(doc, tmp_path_factory)


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _anchors(doc: pathlib.Path) -> set[str]:
    text = re.sub(r"^```.*?^```", "", doc.read_text(encoding="utf-8"), flags=re.M | re.S)
    return {_slug(h) for h in re.findall(r"^#+ (.*)$", text, flags=re.M)}


def test_links_and_cited_sections_resolve():
    """Every relative link of README.md and docs/*.md names a file that exists (and a heading in it), and
    every "NAME §N" in docs, scenes and code names docs/NAME.md with a section N."""
    broken = []
    for doc in DOCS:
        text = re.sub(r"^```.*?^```", "", doc.read_text(encoding="utf-8"), flags=re.M | re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue
            path, _, anchor = target.partition("#")
            file = (doc.parent / path).resolve() if path else doc
            if not file.exists():
                broken.append(f"{doc.relative_to(ROOT)}: {target}: no such file")
            elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
                broken.append(f"{doc.relative_to(ROOT)}: {target}: no such heading")
    sources = [*DOCS, *(ROOT / "runs").glob("*.toml"), *(ROOT / "petroll").rglob("*.py")]
    for source in sources:
        where = source.relative_to(ROOT)
        for name, section in re.findall(r"\b([a-z][\w-]*) §(\d+)", source.read_text(encoding="utf-8")):
            doc = ROOT / "docs" / f"{name}.md"
            if not doc.exists() or not re.search(rf"^## {section}\. ", doc.read_text(encoding="utf-8"), re.M):
                broken.append(f"{where}: {name} §{section}: no such section in docs/{name}.md")
    assert not broken, "\n".join(broken)
