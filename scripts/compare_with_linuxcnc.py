"""Read every test program and every installed LinuxCNC example with precontour and compare
the accepted ones with LinuxCNC 2.9's own interpreter (what
tests/toolpath/test_linuxcnc_reference.py asserts); print one line per program and the
totals: programs compared, moves and arcs, the largest differences, the refusals by reason.

Run from the repository root:  PYTHONPATH=src python scripts/compare_with_linuxcnc.py
"""

import re
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "toolpath"))

from lcnc_compare import (NOT_LINUXCNC, canonical_moves, compare,  # noqa: E402
                          linuxcnc_missing, program_key, program_machine, programs, remap_ini,
                          rs274_moves)

from precontour.errors import PrecontourError  # noqa: E402
from precontour.toolpath import read_program  # noqa: E402


def main() -> None:
    missing = linuxcnc_missing()
    if missing:
        sys.exit(missing)
    totals = Counter()
    worst = dict(end=0.0, centre=0.0, rate=0.0, rs274=0.0)
    refusals = Counter()
    with tempfile.TemporaryDirectory() as folder:
        ini = remap_ini(Path(folder))
        for path in programs():
            key = program_key(path)
            machine = program_machine(path)
            if key in NOT_LINUXCNC:
                continue
            try:
                program = read_program(path, machine)
            except PrecontourError as exc:
                reason = str(exc).split(": ", 1)[1]
                refusals[re.sub(r"line \d+, |'[^']*'|\d+(\.\d+)?", "…", reason)[:70]] += 1
                continue
            result = compare(program, machine, canonical_moves(path, ini),
                             rs274_moves(path, ini))
            totals["programs"] += 1
            totals["moves"] += result.n_moves
            totals["arcs"] += result.n_arcs
            totals["dwells"] += result.n_dwells
            for name in worst:
                worst[name] = max(worst[name], getattr(result, name))
            stop = f", compared up to line {result.stopped_at}" if result.stopped_at else ""
            print(f"{key:45s} {result.n_moves:6d} moves {result.n_arcs:5d} arcs  end "
                  f"{result.end:.1e} mm  centre {result.centre:.1e} mm  rate "
                  f"{result.rate:.1e}  rs274 {result.rs274:.1e} mm{stop}")
    print(f"\n{totals['programs']} programs agree with LinuxCNC: {totals['moves']} moves, "
          f"{totals['arcs']} arcs, {totals['dwells']} dwells; largest differences: end point "
          f"{worst['end']:.2g} mm, arc centre {worst['centre']:.2g} mm, feed rate "
          f"{worst['rate']:.2g} (relative), rs274's 4-decimal printout {worst['rs274']:.2g} mm")
    print(f"{sum(refusals.values())} refused:")
    for reason, count in refusals.most_common():
        print(f"  {count:4d}  {reason}")


if __name__ == "__main__":
    main()
