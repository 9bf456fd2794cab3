"""Compile time of the numerical kernels: what the first run after installing pays.

Runs one command of the CLI in this process (default ``demo``) with an empty numba cache in a
temporary folder (``NUMBA_CACHE_DIR``; ``--cache DIR`` reuses one, e.g. for a warm run), and
records every kernel compilation numba does: per kernel, the signatures compiled and the CPU
seconds of its compiling thread, exclusive of the kernels it calls (they are compiled on their
own first, and listed on their own) and inclusive of the numba implementations of numpy and
builtin functions it needed (also shown on their own). CPU time, not wall time, because the machine this runs on
is shared. Prints a Markdown table per module and kernel, then the totals: compile CPU, process
CPU (user + sys) and wall time.

Run: ``PYTHONPATH=src python benchmarks/bench_compile.py [--cache DIR] [-- demo --out DIR]``
(arguments after ``--`` are the CLI's; the default is ``demo`` into a temporary folder).
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from collections import defaultdict


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    command = None
    if "--" in argv:
        cut = argv.index("--")
        argv, command = argv[:cut], argv[cut + 1:]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", help="numba cache folder (default: a new empty one)")
    parser.add_argument("--top", type=int, default=0, help="print only the N costliest kernels")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="precontour-compile-") as tmp:
        os.environ["NUMBA_CACHE_DIR"] = args.cache or os.path.join(tmp, "numba")
        if command is None:
            command = ["demo", "--out", os.path.join(tmp, "demo")]
        return _measure(command, args.top)


def _measure(command: list[str], top: int) -> int:
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
    print(f"\n`precontour {' '.join(command)}`, numba cache {os.environ['NUMBA_CACHE_DIR']}\n")
    print("| module | compile CPU, s |\n|---|---:|")
    for module, seconds in sorted(by_module.items(), key=lambda item: -item[1]):
        print(f"| {module.removeprefix('precontour.')} | {seconds:.1f} |")
    print("\n| kernel | signatures | compile CPU, s | of which numba's functions, s |\n"
          "|---|---:|---:|---:|")
    for name, seconds in rows[:top or None]:
        print(f"| {name.removeprefix('precontour.')} | {signatures[name]} | {seconds:.2f} | "
              f"{library[name]:.2f} |")
    print(f"\ncompile CPU {sum(total.values()):.1f} s for {len(spent)} kernels "
          f"({sum(signatures.values())} signatures); process CPU {process_cpu:.1f} s "
          f"(user + sys), wall {wall:.1f} s, "
          f"load average {os.getloadavg()[0]:.2f}")
    return status


if __name__ == "__main__":
    sys.exit(main())
