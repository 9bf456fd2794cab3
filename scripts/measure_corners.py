"""Corner tolerance, measured on whole programs: write the ``corners`` section of docs/gcode.md.

Every program is timed as ``precontour trajectory`` times it (``program_trajectory``, the
default corner tolerance or the program's own ``G64 P``), and two distances are measured on
the trajectory's samples, independently of the planner:

- from every programmed point to the polyline through the samples (how far the blend of a
  corner passes from the corner), as a fraction of that point's tolerance;
- from every sample to the programmed polyline (how far the trajectory leaves the path);
- at every programmed point, the least angle between the planned and the programmed tool
  orientation where the planned tip (TCP) or linear axes are within the point's tolerance
  (the corner passed as a pose, ``--corner-ori-tol``).

Both are measured where the tolerance applies: at the tool tip (the direct kinematics of the
joint commands) for TCP moves, in the linear axes otherwise. Programs: LinuxCNC's five-axis
trunnion demos (``--tcp``, on ``linuxcnc-xyzac-trt`` / ``linuxcnc-xyzbc-trt``), the programs of
its ``ncfiles`` that precontour reads (on ``zhang2013``), and the test programs of
``tests/toolpath/data``. Programs that precontour refuses or cannot time are left out.

Run from the repository root:

    python scripts/measure_corners.py [--output docs/gcode.md]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from docpage import DOCS, ROOT, markdown_table, replace_section, stamp
from precontour.defaults import (DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                                 DEFAULT_CORNER_TOLERANCE)
from precontour.errors import PrecontourError
from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_program
from precontour.trajectory import program_trajectory

DEMOS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
             "table-rotary-tilting/demos")
NCFILES = Path("/usr/share/linuxcnc/ncfiles")
DATA = ROOT / "tests" / "toolpath" / "data"


def segment_distance(x, a, b):
    """Distance from each row of x to the segment a[i]-b[i] of the same row."""
    ab = b - a
    den = np.einsum("ij,ij->i", ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(den > 0, np.clip(np.einsum("ij,ij->i", x - a, ab) / den, 0, 1), 0.0)
    return np.linalg.norm(x - (a + u[:, None] * ab), axis=1)


def to_polyline(x, polyline, piece=0.2, k=16):
    """Exact distance from each row of ``x`` to the polyline through ``polyline``: the
    polyline is cut into pieces at most ``piece`` mm long, the ``k`` pieces with the nearest
    midpoints are measured, and where a piece farther out could still be nearer (its midpoint
    within the distance found plus half a piece) all such pieces are."""
    ends = []
    for a, b in zip(polyline[:-1], polyline[1:]):
        m = max(1, int(np.ceil(np.linalg.norm(b - a) / piece)))
        pts = a + np.linspace(0, 1, m + 1)[:, None] * (b - a)
        ends.append((pts[:-1], pts[1:]))
    A = np.concatenate([e[0] for e in ends])
    B = np.concatenate([e[1] for e in ends])
    half = np.linalg.norm(B - A, axis=1).max() / 2
    tree = cKDTree((A + B) / 2)
    k = min(k, len(A))
    near, index = tree.query(x, k=k)
    near, index = near.reshape(len(x), k), index.reshape(len(x), k)
    best = np.full(len(x), np.inf)
    for j in range(k):
        best = np.minimum(best, segment_distance(x, A[index[:, j]], B[index[:, j]]))
    for i in np.flatnonzero(near[:, -1] < best + half):
        found = tree.query_ball_point(x[i], best[i] + half)
        best[i] = min(best[i], segment_distance(np.repeat(x[i:i + 1], len(found), axis=0),
                                                A[found], B[found]).min())
    return best


def orientation_errors(points, orientations, path, path_orientations, tolerance):
    """Per programmed point, the least angle (rad) between the orientation along the
    polyline of the samples (tip or linear axes ``path``, orientation ``path_orientations``,
    both linear between samples) and the programmed one, where the polyline is within the
    point's ``tolerance``; NaN where it never is."""
    tree = cKDTree(path)
    out = np.full(len(points), np.nan)
    for i, found in enumerate(tree.query_ball_point(points, tolerance + 0.5)):
        if not found:
            continue
        k = np.asarray(found)
        k = np.unique(np.clip(np.concatenate([k, k - 1]), 0, len(path) - 2))
        a, b = path[k] - points[i], path[k + 1] - path[k]
        c, d = path_orientations[k] - orientations[i], path_orientations[k + 1] - \
            path_orientations[k]
        bb, ab, aa = (b * b).sum(1), (a * b).sum(1), (a * a).sum(1)
        # the stretch of each segment within the tolerance, and the orientation's least there
        root = np.sqrt(np.maximum(ab * ab - bb * (aa - tolerance[i] ** 2), 0.0))
        dd = (d * d).sum(1)
        with np.errstate(divide="ignore", invalid="ignore"):
            lo = np.clip(np.where(bb > 0, (-ab - root) / bb, 0.0), 0, 1)
            hi = np.clip(np.where(bb > 0, (-ab + root) / bb, 1.0), 0, 1)
            u = np.clip(np.where(dd > 0, -(c * d).sum(1) / dd, 0.0), lo, hi)
        inside = np.linalg.norm(a + u[:, None] * b, axis=1) <= tolerance[i] * (1 + 1e-9)
        if inside.any():
            chord = np.linalg.norm(c + u[:, None] * d, axis=1)[inside].min()
            out[i] = 2.0 * np.arcsin(min(1.0, chord / 2.0))
    return out


def measure(path: Path, machine_name: str, tcp: bool):
    """(points, worst point / tolerance, its line, largest point distance mm, largest sample
    distance mm or None, duration s, worst orientation rad and its line), or None where
    precontour refuses the program."""
    machine = load_machine(machine_name)
    try:
        program = read_program(path, machine, tcp=tcp)
        traj = program_trajectory(program, machine)
    except PrecontourError:
        return None
    tolerance = np.where(np.isnan(program.path_tolerance), DEFAULT_CORNER_TOLERANCE,
                         program.path_tolerance)
    # a point's tolerance: the tighter of the two moves meeting there
    at_point = np.minimum(np.concatenate([tolerance[:1], tolerance]),
                          np.concatenate([tolerance, tolerance[-1:]]))
    tcp_point = np.concatenate([program.tcp_move[:1], program.tcp_move])
    tips, orientations = machine.kinematics.forward(program.points)
    distance = np.zeros(len(tips))
    if tcp_point.any():
        distance[tcp_point] = to_polyline(tips[tcp_point], traj.P)
    if (~tcp_point).any():
        distance[~tcp_point] = to_polyline(program.points[~tcp_point, :3], traj.q[:, :3])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(at_point > 0, distance / at_point, 0.0)
    worst = int(np.argmax(ratio))
    lines = np.concatenate([[program.start_line], program.line])
    leave = None
    if program.tcp_move.all():
        leave = float(to_polyline(traj.P, tips).max())
    elif not program.tcp_move.any():
        leave = float(to_polyline(traj.q[:, :3], program.points[:, :3]).max())
    # the orientation where the tip (TCP) or the linear axes are within the tolerance (a
    # point with none, G61: the path passes it exactly), each point in its own frame
    angle = np.zeros(len(tips))
    tolerance_at = np.maximum(at_point, 1e-9)
    for frame, points, path in ((tcp_point, tips, traj.P),
                                (~tcp_point, program.points[:, :3], traj.q[:, :3])):
        if frame.any():
            angle[frame] = orientation_errors(points[frame], orientations[frame], path, traj.O,
                                              tolerance_at[frame])
    turned = int(np.argmax(np.nan_to_num(angle, nan=np.inf)))
    return (len(tips), float(ratio[worst]), int(lines[worst]), float(distance.max()), leave,
            traj.duration, float(angle[turned]), int(lines[turned]))


def cases():
    for name, machine in (("boat-xyzac.ngc", "linuxcnc-xyzac-trt"),
                          ("impeller-7bl-xyzac.ngc", "linuxcnc-xyzac-trt"),
                          ("boat-xyzbc.ngc", "linuxcnc-xyzbc-trt")):
        if (DEMOS / name).is_file():
            yield f"demos/{name}", DEMOS / name, machine, True
    if NCFILES.is_dir():
        for path in sorted(NCFILES.glob("*.ngc")):
            yield path.name, path, "zhang2013", False
    for path in sorted(DATA.glob("*.n*")):
        yield f"tests/toolpath/data/{path.name}", path, "zhang2013", False


def section() -> str:
    rows = []
    for label, path, machine, tcp in cases():
        result = measure(path, machine, tcp)
        if result is None:
            continue
        n, ratio, line, largest, leave, duration, angle, angle_line = result
        print(f"{label}: {ratio:.3f} of the tolerance at line {line}", file=sys.stderr)
        rows.append([f"`{label}`", machine + (" `--tcp`" if tcp else ""), f"{n:,}",
                     f"{duration:,.1f} s", f"{100 * ratio:.1f} % (line {line})",
                     f"{1e3 * largest:.2f}", "—" if leave is None else f"{1e3 * leave:.2f}",
                     f"{1e3 * angle:.3f} (line {angle_line})"])
    lines = ["## Corner tolerance, measured", "", stamp(), "",
             "Each program timed as `precontour trajectory` times it (corner tolerance "
             f"{DEFAULT_CORNER_TOLERANCE:g} mm, or the program's `G64 P`); distances measured "
             "on the samples, at the tool tip for TCP moves and in the linear axes otherwise: "
             "from each programmed point to the polyline through the samples (the largest as "
             "a share of that point's tolerance, and in um), and from each sample to the "
             "programmed polyline (— where TCP and joint moves mix); and the largest, over "
             "the programmed points, of the least angle between the planned and programmed "
             "tool orientation where the point is within its tolerance (orientation "
             f"tolerance {DEFAULT_CORNER_ORIENTATION_TOLERANCE:g} rad, `--corner-ori-tol`). "
             "Programs precontour refuses are left out.", ""]
    lines.append(markdown_table(
        ["program", "machine", "points", "duration", "worst point / tolerance",
         "largest point distance, um", "largest sample distance, um",
         "worst orientation at a point, mrad"],
        rows, "llrrlrrl"))
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=DOCS / "gcode.md")
    args = parser.parse_args(argv)
    replace_section(args.output, "corners", section())
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
