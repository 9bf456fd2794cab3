"""Write tests/toolpath/data/blade_finish.nc: the CL data of blade_finish.cls (and .csv) in
machine axes of the zhang2013 A-C trunnion, through its inverse kinematics (spec section 1).

The blocks exercise the G-code reader (modal axes and feed, a block-deleted line, a lower-case
block repeating the previous one, comments, tool and spindle words, G43), and every motion
block is one CL point, so the three fixture files describe the same tool path. Positions are
written to 4 decimals (mm and degrees).

Run from the repository root:  python scripts/make_blade_finish_nc.py
"""

import warnings
from pathlib import Path

import numpy as np

from precontour import load_machine
from precontour.toolpath import read_apt_report

DATA = Path(__file__).resolve().parent.parent / "tests" / "toolpath" / "data"


def main() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)   # the file's 7-digit orientations
        cl = read_apt_report(DATA / "blade_finish.cls").toolpath
    q = load_machine("zhang2013").kinematics.inverse(cl.P, cl.O)
    q[:, 3:] = np.degrees(q[:, 3:])

    def words(i, letters):
        return " ".join(f"{axis}{q[i, 'XYZAC'.index(axis)]:.4f}".rstrip("0") for axis in letters)

    lines = [
        "%",
        "O1001 (BLADE FINISH - 5X MACHINE AXES)",
        "(POST: ZHANG2013 A-C TRUNNION, FROM BLADE_FINISH.CLS BY SCRIPTS/MAKE_BLADE_FINISH_NC.PY)",
        "N10 G90 G21 G17 G40 G49 G80",
        "N20 T1 M6",
        "N30 S12000 M3",
        f"N40 G0 {words(0, 'XYZAC')}",
        "N50 G43 H1",
        f"N60 G1 {words(1, 'Z')} F1200. ; plunge, tool along C",
        f"N70 {words(2, 'XYZA')} ( modal C and feed )",
        f"N80 {words(3, 'XYZA')}",
        f"N90 {words(4, 'XYZA')} F900.",
        "/N95 M1",
        f"N100 {words(5, 'XYZA')}",
        f"n110 g1 {words(5, 'XYZAC').lower()}",
        f"N120 G0 {words(6, 'YZ')}",
        "N130 M5",
        "N140 M30",
        "%",
    ]
    (DATA / "blade_finish.nc").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
