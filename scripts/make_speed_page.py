"""Run benchmarks and write their results into docs/speed.md, one stamped section each.

``python scripts/make_speed_page.py NAME [ARGS ...]`` runs ``benchmarks/bench_NAME.py ARGS``
in a fresh process and puts what it prints into the section ``NAME`` of the page (a Markdown
table as it is, anything else as a code block), with the command, the date, the versions and
the computer; the other sections stay as they are. ``--all`` runs every benchmark in
:data:`DEFAULT_RUNS` with its usual arguments, one after the other (about half an hour on an
idle 2-core machine; ``bench_pipeline.py --long`` adds the 10-hour program, a few more minutes).

Timings depend on the computer and on what else runs on it: compare the ratios each benchmark
measures against its baseline in the same run (``lsim / stage``, ``x read + plan``), not the
seconds of different runs.

Run from the repository root:  python scripts/make_speed_page.py [--output docs/speed.md] NAME [ARGS ...]
"""

from __future__ import annotations

import argparse
import ast
import datetime
import os
import subprocess
import sys
from pathlib import Path

from docpage import DOCS, ROOT, load_average, replace_section, stamp

BENCHMARKS = ROOT / "benchmarks"
#: The benchmarks ``--all`` runs, in page order, with their usual arguments.
DEFAULT_RUNS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("pipeline", ()),
    ("simulation", ()),
    ("predict", ()),
    ("trajectory", ()),
    ("readers", ()),
    ("program", ()),
    ("run", ("4",)),
    ("nearest", ()),
    ("jobs", ()),
    ("profile", ("--top", "20")),
)

INTRO = """# Speed, measured

Time and memory of each stage, measured by the benchmarks in `benchmarks/`; each section is
written by one run of `scripts/make_speed_page.py NAME` (which runs `benchmarks/bench_NAME.py`),
stamped with its date, versions and computer; do not edit by hand. The computer is shared and
small (2 cores): compare the ratios each benchmark measures against its own baseline in the
same run (`lsim / stage`: how many times faster than `scipy.signal.lsim` of the five closed
loops on the same samples; `x read + plan`), not the seconds of different runs."""


def description(name: str) -> str:
    """The first line of a benchmark's docstring (read without importing it)."""
    tree = ast.parse((BENCHMARKS / f"bench_{name}.py").read_text())
    doc = ast.get_docstring(tree) or f"bench_{name}.py"
    text = " ".join(doc.split("\n\n")[0].split()).replace("``", "`")
    return text.removesuffix(" (a script, not a test).").rstrip(".")


def run_benchmark(name: str, args: list[str]) -> str:
    script = BENCHMARKS / f"bench_{name}.py"
    if not script.is_file():
        raise SystemExit(f"make_speed_page: no benchmark {script.relative_to(ROOT)}")
    env = dict(os.environ)
    # the benchmarks import precontour: the source tree when it is not installed
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")]))
    done = subprocess.run([sys.executable, str(script), *args], cwd=ROOT, env=env,
                          capture_output=True, text=True)
    if done.returncode != 0:
        sys.stderr.write(done.stderr)
        raise SystemExit(f"make_speed_page: bench_{name}.py failed (exit {done.returncode}); "
                         "the page is unchanged")
    return done.stdout


def section(name: str, args: list[str], output: str, started: datetime.datetime,
            load: float | None) -> str:
    command = " ".join(["python", f"benchmarks/bench_{name}.py", *args])
    lines = output.strip("\n").splitlines()
    table = any(line.startswith("|") for line in lines)
    body = "\n".join(lines) if table else "\n".join(["```", *lines, "```"])
    return "\n".join([f"## {description(name)}", "",
                      stamp(command, started=started, load=load) + f" Regenerate: `python scripts/make_speed_page.py "
                      f"{' '.join([name, *args])}`.", "", body])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", type=Path, default=DOCS / "speed.md",
                        help="page to write (default docs/speed.md)")
    parser.add_argument("--all", action="store_true", help="run every default benchmark")
    parser.add_argument("name", nargs="?", help="benchmark: benchmarks/bench_NAME.py")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="its arguments")
    args = parser.parse_args(argv)
    runs = list(DEFAULT_RUNS) if args.all else [(args.name, tuple(args.args))]
    if runs == [(None, ())]:
        parser.error("give a benchmark NAME or --all")
    replace_section(args.output, "intro", INTRO)
    for name, bench_args in runs:
        print(f"running bench_{name}.py {' '.join(bench_args)}", file=sys.stderr, flush=True)
        started, load = datetime.datetime.now(), load_average()
        output = run_benchmark(name, list(bench_args))
        text = section(name, list(bench_args), output, started, load)
        replace_section(args.output, name, text)
        print(f"wrote section {name} of {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
