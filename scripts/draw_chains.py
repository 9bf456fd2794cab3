"""Draw the kinematic chain of each built-in machine family: the axis lines, the spindle nose,
the tool and the part at one pose, from the machine's chain (precontour.machine.kinematics
.chain_of), in the machine frame.

Run from the repository root:  PYTHONPATH=src python scripts/draw_chains.py
                               -> docs/chains/<machine>.png
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from precontour import load_machine  # noqa: E402
from precontour.machine.kinematics.chain import turn_about, chain_of  # noqa: E402

OUT = Path(__file__).resolve().parent.parent / "docs" / "chains"
MACHINES = ("zhang2013", "linuxcnc-xyzbc-trt", "head-table-bc", "linuxcnc-bridgemill",
            "head-table-ac", "linuxcnc-xyzab-tdr")
#: The pose drawn: linear axes (mm), the rotary axes in slots 3 and 4 (rad).
POSE = np.array([0.0, 0.0, 0.0, np.radians(35.0), np.radians(50.0)])
#: Where the part is drawn, in the workpiece frame (default its origin): on the A-B table the
#: A table's face centre (rotation point + offsets), where LinuxCNC's demo puts its G54.
PART_CENTRE = {"linuxcnc-xyzab-tdr": (-70.0, -50.0, -110.0)}
AXIS_HALF = 120.0   # mm of each axis line drawn either side of its point
PART = 60.0         # mm, half side of the square drawn on the part


def _placed(chain, rotary, axis, point, direction=False):
    """A point (or direction) of ``axis``'s own link moved by the axes carrying it: on a head
    the head axes nearer the ram, on a table the table axes nearer the base."""
    x = np.asarray(point, dtype=float)
    links = chain._head_axes() if axis.side == "head" else chain._table_axes()
    index = [a for a, _ in links].index(axis)
    for carrier, slot in links[index + 1:]:
        x = turn_about(x, carrier, rotary[slot - 3], direction=direction)
    return x


def draw(name: str) -> Path:
    machine = load_machine(name)
    chain = chain_of(machine.kinematics)
    q = POSE.copy()
    centre = np.asarray(PART_CENTRE.get(name, (0.0, 0.0, 0.0)))
    q[:3] = chain.linear_axes(centre, q[3], q[4])   # the tip at the part's centre
    rotary = q[3:]
    home = q[:3] * np.asarray(chain.linear_senses)   # the spindle nose at the zero pose
    tip = home + chain._tool(rotary, False)
    nose = tip + chain.tool_offset * chain._tool(rotary, True)   # where the head puts it
    fig = plt.figure(figsize=(7, 6.5))
    ax = fig.add_subplot(projection="3d")
    seen = [tip, nose, home]   # what the view must hold
    for (axis, _), colour in zip(chain.rotary_axes, ("tab:red", "tab:blue")):
        point = _placed(chain, rotary, axis, axis.point)
        direction = _placed(chain, rotary, axis, axis.direction, direction=True)
        if axis.side == "head":
            # head points are relative to the spindle nose at the zero pose
            point = point + home
        ends = np.array([point - AXIS_HALF * direction, point + AXIS_HALF * direction])
        ax.plot(*ends.T, color=colour, lw=2,
                label=f"{axis.letter} axis ({axis.side}), direction {list(axis.direction)}")
        ax.scatter(*point, color=colour, s=20)
        seen.append(point)
    if chain._head_axes():   # the spindle's housing: the pivot nearest the tool to the nose
        nearest = chain._head_axes()[0][0]
        pivot = home + np.asarray(_placed(chain, rotary, nearest, nearest.point))
        ax.plot(*np.array([pivot, nose]).T, color="0.6", lw=6, label="head (pivot to nose)")
    ax.plot(*np.array([nose, tip]).T, color="k", lw=3,
            label=f"tool ({chain.tool_offset:g} mm, nose to tip)")
    ax.scatter(*nose, color="k", s=25, marker="s", label="spindle nose")
    where = "A table face centre" if name in PART_CENTRE else "part origin"
    ax.scatter(*tip, color="tab:orange", s=25, label=f"tool tip ({where})")
    # the part: a square in the workpiece frame's xy plane, where the table puts it
    square = PART * np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [-1, -1, 0]])
    placed = square + centre + np.asarray(chain.workpiece_origin)
    for table_axis, slot in chain._table_axes():
        placed = turn_about(placed, table_axis, rotary[slot - 3])
    ax.plot(*placed.T, color="tab:green", lw=1.5, label="part (workpiece frame xy)")
    cloud = np.vstack([placed, *seen])
    centre, half = cloud.mean(axis=0), 0.6 * np.ptp(cloud, axis=0).max()
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    first, second = machine.axis_names[3:]
    ax.set_title(f"{name} ({type(machine.kinematics).__name__}): {first} = "
                 f"{np.degrees(q[3]):.0f} deg, {second} = {np.degrees(q[4]):.0f} deg",
                 fontsize=10)
    ax.legend(loc="upper left", fontsize=7)
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.png"
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


if __name__ == "__main__":
    for machine_name in MACHINES:
        print(draw(machine_name))
