"""Many programs at once: ``run`` over a set of programs and machines (``precontour batch``).

A CAM department compensates hundreds of programs a week for a fleet of machines. This module
owns that fan-out and nothing of the computation: each program on each machine is one
:func:`~precontour.workflow.run_program` and :func:`~precontour.workflow.write_run_outputs`,
exactly as ``precontour run`` does it, in a task of its own on an executor of whole programs
(:func:`~precontour.parallel.program_executor`: processes here, or the workers of a Dask
distributed cluster). A task runs its stages with one job (the executor already keeps the cores
busy), and results do not depend on the jobs, so a batch writes, bit for bit, what the single
runs write. A program that fails is reported with its one-line error; the others go on.
"""

from __future__ import annotations

import inspect
import logging
import time
from collections.abc import Callable, Sequence
from concurrent.futures import as_completed
from dataclasses import dataclass
from pathlib import Path

from .errors import NOTE, NOTICES, InputError, PrecontourError
from .parallel import check_jobs, program_executor, using_jobs
from .toolpath import EXTENSIONS
from .workflow import GCODE_SUFFIXES, RunOutputs, run_program, write_run_outputs

__all__ = ["BatchJob", "BatchEntry", "BatchResult", "batch_jobs", "run_batch"]

#: The extensions a folder's files are taken as programs by (G-code and CL data).
PROGRAM_SUFFIXES: tuple[str, ...] = tuple(sorted({s for suffixes in EXTENSIONS.values()
                                                  for s in suffixes}))
#: The keywords of :func:`~precontour.workflow.run_program` a batch passes on (all but the
#: program, its outputs, the machine and the progress, which the batch gives each task).
RUN_KEYWORDS = frozenset(inspect.signature(run_program).parameters) - {
    "program", "outputs", "machine", "progress", "workers"}


@dataclass(frozen=True)
class BatchJob:
    """One program on one machine, and where its compensated program goes (``stream``,
    ``commands``: its halstreamer file and command table, where asked for)."""

    program: Path
    machine: str
    outputs: RunOutputs


@dataclass(frozen=True)
class BatchEntry:
    """What one program of a batch gave: the files written (none where it failed), its
    one-line error (None where it succeeded), the simulated errors before and after (the
    machine file's machine; ``tip_max_um`` ..., as ``ContourErrors.summary()``), the planned
    and the compensated cycle time, the lines worse than uncompensated, the table ``run``
    prints, its notices, and the seconds it took."""

    job: BatchJob
    files: tuple[Path, ...] = ()
    error: str | None = None
    before: dict | None = None
    after: dict | None = None
    planned_seconds: float | None = None
    final_seconds: float | None = None
    lines_worse: int | None = None
    table: str | None = None
    seconds: float = 0.0
    #: What the run said on the way, in order: (label, message), the label ``note`` or
    #: ``warning`` (what ``run`` prints on stderr as ``precontour: note: ...``, ``warning``).
    notices: tuple[tuple[str, str], ...] = ()

    @property
    def ok(self) -> bool:
        return self.error is None

    def line(self) -> str:
        """One line for the batch's report."""
        name = f"{self.job.program} on {self.job.machine}"
        if not self.ok:
            return f"{name}: failed: {self.error}"
        return (f"{name}: tip max {self.before['tip_max_um']:.3g} -> "
                f"{self.after['tip_max_um']:.3g} um, orientation max "
                f"{self.before['ori_max_mrad']:.3g} -> {self.after['ori_max_mrad']:.3g} mrad, "
                f"{self.planned_seconds:.1f} -> {self.final_seconds:.1f} s, "
                f"{self.lines_worse} line(s) worse; wrote {self.files[0]} "
                f"({self.seconds:.1f} s)")


@dataclass(frozen=True)
class BatchResult:
    """The entries of a batch, in the order of its jobs."""

    entries: tuple[BatchEntry, ...]
    seconds: float

    @property
    def failed(self) -> tuple[BatchEntry, ...]:
        return tuple(e for e in self.entries if not e.ok)

    def summary(self) -> str:
        lines = [e.line() for e in self.entries]
        lines.append(f"{len(self.entries) - len(self.failed)} of {len(self.entries)} "
                     f"program(s) compensated in {self.seconds:.1f} s"
                     + (f"; {len(self.failed)} failed" if self.failed else ""))
        return "\n".join(lines)


def _programs(paths: Sequence[str | Path]) -> list[Path]:
    """The programs named: files as given, a folder's files with a program extension
    (:data:`PROGRAM_SUFFIXES`), sorted by name."""
    found = []
    for path in map(Path, paths):
        if path.is_dir():
            inside = sorted(p for p in path.iterdir()
                            if p.is_file() and p.suffix.lower() in PROGRAM_SUFFIXES)
            if not inside:
                raise InputError("no programs in this folder (files ending "
                                 f"{', '.join(PROGRAM_SUFFIXES)})", source=str(path))
            found += inside
        elif path.is_file():
            found.append(path)
        else:
            raise InputError("no such file or folder", source=str(path))
    return found


def _machine_label(machine: str | Path) -> str:
    return Path(str(machine)).stem if Path(str(machine)).exists() else str(machine)


def batch_jobs(programs: Sequence[str | Path], out_dir: str | Path, *,
               machines: Sequence[str | Path], stream: bool = False,
               commands: bool = False) -> list[BatchJob]:
    """Every program (files, or folders of them) on every machine, with its outputs in
    ``out_dir``: the program's own name (a G-code extension kept, CL data written as
    ``.ngc``), under ``out_dir/MACHINE/`` where there are several machines; ``stream``,
    ``commands``: also ``NAME.txt`` and ``NAME.csv`` beside it. Checked before anything is
    computed: no output is an input, no two jobs write the same file."""
    if not machines:
        raise InputError("give at least one machine", field="--machine")
    labels = [_machine_label(m) for m in machines]
    if len(set(labels)) != len(labels):
        raise InputError(f"two machines share a name ({', '.join(labels)}): their outputs "
                         "would go to the same folder", field="--machine")
    paths = _programs(programs)
    out_dir = Path(out_dir)
    inputs = {p.resolve() for p in paths} | {Path(str(m)).resolve() for m in machines
                                              if Path(str(m)).exists()}
    jobs, seen = [], {}
    for machine, label in zip(machines, labels):
        folder = out_dir / label if len(machines) > 1 else out_dir
        for program in paths:
            suffix = program.suffix if program.suffix.lower() in GCODE_SUFFIXES else ".ngc"
            output = folder / (program.stem + suffix)
            outputs = RunOutputs(program=output,
                                 stream=output.with_suffix(".txt") if stream else None,
                                 commands=output.with_suffix(".csv") if commands else None)
            for path in outputs.files():
                if path.resolve() in inputs:
                    raise InputError("the output would overwrite an input; give another output "
                                     "folder", source=str(path), field="--out-dir")
                if path.resolve() in seen:
                    raise InputError(f"both {seen[path.resolve()]} and {program} would be "
                                     "written here (programs of the same name)",
                                     source=str(path))
                seen[path.resolve()] = program
            jobs.append(BatchJob(program=program, machine=str(machine), outputs=outputs))
    return jobs


def run_batch(programs: Sequence[str | Path], out_dir: str | Path, *,
              machines: Sequence[str | Path], controller: str, stream: bool = False,
              commands: bool = False, executor: str | None = None, jobs: int | None = None,
              progress: Callable[[int, int, str], None] | None = None,
              **run_options) -> BatchResult:
    """``run`` on every program of ``programs`` (files, or folders of them) on every machine
    of ``machines`` with ``controller``, each writing its compensated program into
    ``out_dir`` (:func:`batch_jobs` names them), as ``precontour run`` would write it.

    ``executor``: None, processes on this machine, ``jobs`` of them (default all cores:
    :func:`~precontour.parallel.jobs`); ``dask://HOST:PORT``, the workers of that Dask
    distributed scheduler. ``run_options``: keywords of
    :func:`~precontour.workflow.run_program` (``tcp``, ``learn``, ``draws``,
    ``corner_tolerance`` ...), the same for every program. ``progress(done, total, message)``
    (``run``'s protocol) is called as each program ends, with its line
    (:meth:`BatchEntry.line`). A program that fails (bad input, limits it cannot keep, a
    tolerance it cannot meet) is an entry with its error; the others go on."""
    unknown = sorted(set(run_options) - RUN_KEYWORDS)
    if unknown:
        raise InputError(f"not an option of run: {', '.join(unknown)}", field="run_options")
    if jobs is not None:
        check_jobs(jobs, "--jobs")
    tasks = batch_jobs(programs, out_dir, machines=machines, stream=stream,
                       commands=commands)
    start = time.perf_counter()
    entries: list[BatchEntry | None] = [None] * len(tasks)
    with program_executor(executor, workers=jobs) as pool:
        for folder in {job.outputs.program.parent for job in tasks}:
            folder.mkdir(parents=True, exist_ok=True)
        futures = {pool.submit(_run_one, job, controller, run_options): i
                   for i, job in enumerate(tasks)}
        for done, future in enumerate(as_completed(futures), 1):
            i = futures[future]
            entries[i] = future.result()
            if progress is not None:
                progress(done, len(tasks), entries[i].line())
    return BatchResult(entries=tuple(entries), seconds=time.perf_counter() - start)


def _run_one(job: BatchJob, controller: str, run_options: dict) -> BatchEntry:
    """One program of a batch, in a worker: ``run_program`` and its outputs, with one job;
    its notices collected, a failure made the entry's error."""
    start = time.perf_counter()
    inputs = [job.program] + ([Path(job.machine)] if Path(job.machine).exists() else [])
    notices = _Collected()
    NOTICES.addHandler(notices)
    propagate, NOTICES.propagate = NOTICES.propagate, False
    try:
        with using_jobs(1):
            result = run_program(job.program, job.outputs, machine=job.machine,
                                 controller=controller, **run_options)
            files = write_run_outputs(result, job.outputs, inputs)
    except (PrecontourError, OSError, MemoryError) as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        return BatchEntry(job=job, error=message, seconds=time.perf_counter() - start,
                          notices=tuple(notices.messages))
    finally:
        NOTICES.removeHandler(notices)
        NOTICES.propagate = propagate
    return BatchEntry(job=job, files=tuple(files), before=result.simulated_before.summary(),
                      after=result.simulated_after.summary(),
                      planned_seconds=result.planned.duration,
                      final_seconds=result.commands.duration,
                      lines_worse=len(result.worse_lines()), table=result.table(),
                      seconds=time.perf_counter() - start, notices=tuple(notices.messages))


class _Collected(logging.Handler):
    """The notices of one program, kept for its entry (a worker's stderr is not the user's)."""

    def __init__(self):
        super().__init__()
        self.messages: list[tuple[str, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append((getattr(record, "label", NOTE), record.getMessage()))
