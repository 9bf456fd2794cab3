"""Compile time of the numerical kernels, and the first and later ``precontour demo``.

What the first run after installing pays: numba compiles every kernel a command uses once,
then loads it from its cache. This script measures, with an empty numba cache in a temporary
folder (``NUMBA_CACHE_DIR``; the package's own ``__pycache__`` is not touched):

1. ``precontour demo`` in a fresh process on the empty cache, then three times more on the
   cache it filled: wall time, CPU time (user + sys of the process) and the load average.
2. The same command in one process on another empty cache, recording every compilation
   numba does: per kernel, the signatures compiled and the CPU seconds of its compiling
   thread, exclusive of the kernels it calls (compiled on their own first and listed on
   their own) and inclusive of numba's implementations of the numpy and builtin functions it
   needed. CPU time, because the machine this runs on is shared and its wall time noisy.

Prints Markdown; ``--markdown FILE`` also writes it as a page stamped with the date, the
version and the machine (``docs/speed_first_run.md``).

Run: ``PYTHONPATH=src python benchmarks/bench_compile.py [--markdown FILE] [--no-runs]
[--top N] [--baseline OLD/src [--baseline-label TEXT]] [-- CLI arguments]`` (after ``--``:
the command measured in step 2, default ``demo`` into a temporary folder). ``--baseline``
measures an older version the same way, after this one (its source folder, e.g. from
``git archive``).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

#: Warm runs of the demo after the cold one.
WARM_RUNS = 3
_MARK = "\n--- compile table ---\n"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    command = None
    if "--" in argv:
        cut = argv.index("--")
        argv, command = argv[:cut], argv[cut + 1:]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--markdown", type=Path, help="also write the results to this file")
    parser.add_argument("--no-runs", action="store_true",
                        help="skip step 1 (the demo in fresh processes)")
    parser.add_argument("--top", type=int, default=0, help="list only the N costliest kernels")
    parser.add_argument("--baseline", metavar="SRC", type=Path,
                        help="also measure the package in this source folder (an older "
                             "version), after the current one")
    parser.add_argument("--baseline-label", metavar="TEXT", default="baseline",
                        help="how the page names the --baseline version")
    parser.add_argument("--in-process", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.in_process:
        return _compile_table(command, args.top)
    trees = [("This version", None)]
    if args.baseline:
        trees.append((args.baseline_label, args.baseline.resolve()))
    lines = [f"Measured {datetime.datetime.now():%Y-%m-%d %H:%M} with "
             f"`benchmarks/bench_compile.py`: {_versions()}; {os.cpu_count()} cores "
             f"({platform.machine()}).", ""]
    for label, source in trees:
        env = dict(os.environ)
        if source is not None:
            env["PYTHONPATH"] = os.pathsep.join([str(source), env.get("PYTHONPATH", "")])
            lines += [f"## {label}", ""]
        elif args.baseline:
            lines += [f"## {label}", ""]
        with tempfile.TemporaryDirectory(prefix="precontour-compile-") as tmp:
            if not args.no_runs:
                lines += _demo_runs(Path(tmp), env)
            env["NUMBA_CACHE_DIR"] = os.path.join(tmp, "numba-table")
            table = subprocess.run(
                [sys.executable, __file__, "--in-process", "--top", str(args.top), "--",
                 *(command or ["demo", "--out", os.path.join(tmp, "table-demo")])],
                env=env, check=True, capture_output=True, text=True).stdout
            lines += table.split(_MARK, 1)[1].splitlines() + [""]  # (after the demo's output)
    text = "\n".join(lines)
    print(text, end="")
    if args.markdown:
        args.markdown.write_text("# Compile time and the first run\n\n"
                                 + "\n\n".join(__doc__.split("\n\n")[1:3]) + "\n\n" + text)
    return 0


def _versions() -> str:
    import llvmlite
    import numba
    import numpy

    import precontour

    try:
        commit = subprocess.run(["git", "-C", str(Path(__file__).parent), "describe",
                                 "--always", "--dirty"], capture_output=True, text=True,
                                check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return (f"precontour {precontour.__version__} (commit {commit}), Python "
            f"{platform.python_version()}, numba {numba.__version__}, llvmlite "
            f"{llvmlite.__version__}, numpy {numpy.__version__}")


def _demo_runs(tmp: Path, env: dict) -> list[str]:
    """``precontour demo`` in fresh processes: once on an empty cache, then warm."""
    env = dict(env, NUMBA_CACHE_DIR=str(tmp / "numba-runs"))
    rows = ["| run | wall (s) | CPU (s) | demo's own timer: compute + report (s) | "
            "load average before / after |", "|---|---:|---:|---:|---|"]
    for run in range(1 + WARM_RUNS):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        load = os.getloadavg()[0]
        start = time.perf_counter()
        out = subprocess.run([sys.executable, "-m", "precontour", "demo", "--out",
                              str(tmp / "demo")], env=env, check=True, capture_output=True,
                             text=True)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        own = next((line.split(" in ")[1].split(" s;")[0] for line in out.stdout.splitlines()
                    if line.startswith("wrote ")), "?")
        name = "first (empty cache)" if run == 0 else f"later #{run}"
        rows.append(f"| {name} | {wall:.1f} | {cpu:.1f} | {own} | {load:.2f} / "
                    f"{os.getloadavg()[0]:.2f} |")
    return ["`precontour demo` in a fresh process, numba cache empty before the first run:",
            ""] + rows + [""]


def _compile_table(command: list[str], top: int) -> int:
    """In this process (cache dir already set): run ``command``, print the compile table."""
    start_wall = time.perf_counter()
    start = resource.getrusage(resource.RUSAGE_SELF)
    from numba.core import event

    spent = defaultdict(float)          # kernel -> exclusive compile CPU seconds
    library = defaultdict(float)        # kernel -> numba's own functions compiled for it
    signatures = defaultdict(int)
    stack = []                          # per compile in progress: [name, start CPU, nested]

    class Recorder(event.Listener):
        def on_start(self, ev):
            py_func = ev.data["dispatcher"].py_func
            stack.append([f"{py_func.__module__}.{py_func.__qualname__}",
                          time.thread_time(), 0.0])

        def on_end(self, ev):
            name, began, nested = stack.pop()
            total = time.thread_time() - began
            if name.startswith("precontour."):
                spent[name] += total - nested
                signatures[name] += 1
            else:
                # numba's implementation of a numpy or builtin function: billed to the
                # project kernel that needed it
                owner = next((entry[0] for entry in reversed(stack)
                              if entry[0].startswith("precontour.")), "(outside)")
                library[owner] += total - nested
            if stack:
                stack[-1][2] += total

    event.register("numba:compile", Recorder())
    from precontour.cli import main as cli_main
    status = cli_main(command)
    end = resource.getrusage(resource.RUSAGE_SELF)
    wall = time.perf_counter() - start_wall
    process_cpu = (end.ru_utime - start.ru_utime) + (end.ru_stime - start.ru_stime)

    total = {name: spent[name] + library[name] for name in set(spent) | set(library)}
    rows = sorted(total.items(), key=lambda item: -item[1])
    by_module = defaultdict(float)
    for name, seconds in rows:
        by_module[name.rsplit(".", 1)[0]] += seconds
    shown = " ".join("DIR" if arg.startswith(tempfile.gettempdir()) else arg for arg in command)
    print(f"{_MARK}`precontour {shown}` in one process, numba cache empty: compile "
          f"CPU {sum(total.values()):.1f} s for {len(spent)} kernels "
          f"({sum(signatures.values())} signatures); process CPU {process_cpu:.1f} s "
          f"(user + sys), wall {wall:.1f} s, load average {os.getloadavg()[0]:.2f} at the "
          "end.\n")
    print("| module | compile CPU (s) |\n|---|---:|")
    for module, seconds in sorted(by_module.items(), key=lambda item: -item[1]):
        print(f"| {module.removeprefix('precontour.')} | {seconds:.1f} |")
    print("\n| kernel | signatures | compile CPU (s) | of which numba's functions (s) |\n"
          "|---|---:|---:|---:|")
    for name, seconds in rows[:top or None]:
        print(f"| {name.removeprefix('precontour.')} | {signatures[name]} | {seconds:.2f} | "
              f"{library[name]:.2f} |")
    return status


if __name__ == "__main__":
    sys.exit(main())
