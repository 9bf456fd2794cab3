"""Peak memory per trajectory sample of each command (precontour.defaults.BYTES_PER_SAMPLE).

Runs each command in a fresh process on the built-in ``paper`` path planned at two feeds (so
at two sample counts) and reports the growth of the peak resident set size per extra sample:
the per-sample cost, without the interpreter's and libraries' fixed footprint.

    python scripts/measure_memory.py [--feeds 100,25]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path


def peak_rss(args: list[str], cwd: Path) -> int:
    """Peak RSS (bytes) of ``python -m precontour args`` in a child process."""
    code = ("import resource, sys; from precontour.cli import main; rc = main(sys.argv[1:]); "
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss); sys.exit(rc)")
    out = subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, check=True,
                         capture_output=True, text=True).stdout
    return int(out.split()[-1]) * 1024  # ru_maxrss is in KiB on Linux


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--feeds", default="100,25")
    feeds = [float(f) for f in parser.parse_args().feeds.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)
        counts, peaks = [], {}
        for feed in feeds:
            traj = f"paper_{feed:g}.csv"
            peaks.setdefault("trajectory", []).append(peak_rss(
                ["trajectory", "--builtin", "paper", "--feed", str(feed), "-o", traj], cwd))
            counts.append(sum(1 for _ in open(cwd / traj)) - 1)
            for name, args in (
                    ("predict", ["predict", traj, "-o", "pred.csv"]),
                    ("compensate", ["compensate", traj, "-o", "comp.csv"]),
                    ("simulate", ["simulate", "comp.csv", "-o", "sim.csv"]),
                    ("compare", ["compare", traj, "--out", "cmp"])):
                peaks.setdefault(name, []).append(peak_rss(args, cwd))
        extra = counts[-1] - counts[0]
        print(f"samples: {counts}")
        for name, values in peaks.items():
            per = (values[-1] - values[0]) / extra
            print(f"{name:>11}: peak RSS {', '.join(f'{v / 2**20:.0f} MiB' for v in values)}; "
                  f"{per:,.0f} bytes per sample")


if __name__ == "__main__":
    main()
