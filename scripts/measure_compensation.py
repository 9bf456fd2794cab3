"""Measure contour-error reductions on the virtual machine for the README and docs/compensation.md.

For each path and PID controller: pre-compensate with 1 pass (the paper's procedure), with up
to 4 passes, and with 1 pass plus learning against the ensemble of realistic virtual machines
(``compensate(..., machine_actual=ensemble_actual(...))``, ``compensate --ignore-limits
--learn 4``: every choice on the worst of the ensemble's draws; ``scripts/measure_robust.py``
measures learning within the limits, the CLI default); run the original and
the compensated commands on
- the exact linear machine (continuous PID, no friction),
- the realistic machine (discrete PID at 1 kHz, friction, feed-forward friction compensation),
- the realistic machine whose true inertia J and damping B are 20 % above / below the values
  the predictor (and the learning) used (a mis-identified machine),
and print, as Markdown,
1. the contour errors and their reductions (max and mean, tip and orientation),
2. on the realistic machine: the time and place of the largest tip error before compensation,
   after the linear pass and after learning, which command learning kept, and what it cost.

Paths: the built-in ones, and test paths whose stops and reversals differ from theirs
(``--test-paths``): ``fan25``, a 25-point fan-like sweep whose tip reverses in x, ending while
the tool still turns; ``flank``, a flank path between two B-spline curves (tool from the lower
to the upper curve); ``interior-stop``, a move that stops for 0.1 s halfway and then goes on.

Run: ``python scripts/measure_compensation.py --test-paths --output docs/compensation.md``
(without ``--output`` the page goes to stdout); its last section holds the two summary tables.
The page is stamped with the date, the versions and the computer (``docpage.stamp``).
"""

from __future__ import annotations

import contextlib
import io
import sys
import time
from pathlib import Path

import numpy as np
from scipy.interpolate import make_interp_spline

from docpage import stamp, write_page
from precontour import load_machine, load_servo
from precontour.compensation.precompensate import compensate
from precontour.compensation.stops import DEFAULT_LEARNING_PASSES, final_rest_index
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.ensemble import ensemble_actual
from precontour.simulation.virtual_machine import simulate
from precontour.toolpath import ToolPath
from precontour.trajectory.builtin_paths import BUILTIN_PATHS, builtin_path
from precontour.trajectory.generate import generate_trajectory
from precontour.trajectory.sampled import Trajectory

MACHINES = {
    "exact": dict(mode="continuous", friction=False, ff_friction=False),
    "realistic": dict(mode="discrete", friction=True, ff_friction=True),
    "J,B +20 %": dict(mode="discrete", friction=True, ff_friction=True, inertia_scale=1.2,
                      damping_scale=1.2),
    "J,B -20 %": dict(mode="discrete", friction=True, ff_friction=True, inertia_scale=0.8,
                      damping_scale=0.8),
}
KEYS = ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad")
CONTROLLERS = ("pid-high", "pid-low")
TEST_PATHS = ("fan25", "flank", "interior-stop")


def _orientation(tilt_x, tilt_y):
    O = np.stack([np.sin(tilt_y), np.sin(tilt_x) * np.cos(tilt_y),
                  np.cos(tilt_x) * np.cos(tilt_y)], axis=-1)
    return O / np.linalg.norm(O, axis=1, keepdims=True)


def fan25_path() -> ToolPath:
    """25 points: the tip goes out and back in x (a reversal mid-path) along y, the tool fans
    about x to 0.5 rad and back through vertical and ends while still turning."""
    u = np.linspace(0.0, 1.0, 25)
    P = np.stack([20.0 * np.sin(np.pi * u), 60.0 * u - 30.0, 4.0 * np.sin(2 * np.pi * u)], axis=1)
    return ToolPath(P=P, O=_orientation(0.5 * np.sin(1.75 * np.pi * u), 0.1 + 0.15 * u),
                    source="<test path fan25>")


def flank_path() -> ToolPath:
    """Flank milling between two cubic B-spline curves: tip on the lower, tool towards the
    upper (30 mm above, shifted and twisted), 40 points."""
    s = np.linspace(0.0, 1.0, 40)
    knots_u = np.linspace(0.0, 1.0, 6)
    lower = make_interp_spline(knots_u, np.array(
        [[-40, -10, 0], [-20, 8, 2], [0, 12, 0], [20, 4, -3], [35, -12, 0], [45, -25, 2.0]]), k=3)
    upper = make_interp_spline(knots_u, np.array(
        [[-35, -18, 30], [-18, 2, 31], [4, 16, 30], [18, 12, 28], [38, -4, 30], [52, -14, 31.0]]),
        k=3)
    P, top = lower(s), upper(s)
    O = (top - P) / np.linalg.norm(top - P, axis=1, keepdims=True)
    return ToolPath(P=P, O=O, source="<test path flank>")


def interior_stop_trajectory(machine) -> Trajectory:
    """A curved move that stops, rests 0.1 s, and goes on along another curve (an interior
    stop, with the tool turning on both sides of it), then the usual final dwell."""
    u = np.linspace(0.0, 1.0, 60)
    first = ToolPath(P=np.stack([40 * u - 40, 15 * np.sin(np.pi * u), 3 * u], axis=1),
                     O=_orientation(0.1 + 0.3 * u, 0.2 * np.sin(np.pi * u)))
    second = ToolPath(P=np.stack([first.P[-1, 0] + 30 * u, first.P[-1, 1] - 20 * u ** 2,
                                  first.P[-1, 2] + 2 * np.sin(np.pi * u)], axis=1),
                      O=_orientation(0.4 - 0.5 * u, -0.3 * np.sin(np.pi * u)))
    a = generate_trajectory(first, machine, dwell=0.1)
    b = generate_trajectory(second, machine)
    if not np.allclose(a.q[-1], b.q[0], atol=1e-9):
        raise RuntimeError("the two moves of interior-stop do not meet on the same axis branch")
    t = np.concatenate([a.t, a.t[-1] + a.ts + b.t])
    return Trajectory(t=t, q=np.concatenate([a.q, b.q]), P=np.concatenate([a.P, b.P]),
                      O=np.concatenate([a.O, b.O]))


def trajectory_of(name: str, machine) -> Trajectory:
    if name == "interior-stop":
        return interior_stop_trajectory(machine)
    toolpath = {"fan25": fan25_path, "flank": flank_path}.get(name)
    return generate_trajectory(toolpath() if toolpath else builtin_path(name), machine)


def where(traj: Trajectory, index: int, short: bool = False) -> str:
    """Time of a sample, and its place: in motion, or into the final dwell."""
    rest = final_rest_index(traj.q)
    t = traj.t[index]
    if rest is not None and index >= rest:
        dwell = "the dwell" if short else "the final dwell"
        return f"{t:.3f} s ({1e3 * (t - traj.t[rest]):.0f} ms into {dwell})"
    stop = traj.t[rest] if rest is not None else traj.t[-1]
    if short:
        return f"{t:.3f} s ({1e3 * (stop - t):.0f} ms before the stop)"
    return f"{t:.3f} s (in motion, {1e3 * (stop - t):.0f} ms before the final stop)"


def _name(path: str) -> str:
    return f"`{path}`" if path in TEST_PATHS else path


def main(paths: list[str]) -> None:
    machine = load_machine("zhang2013")
    start = time.perf_counter()
    rows, places = [], []
    readme_rows, readme_places = [], []
    for path in paths:
        traj = trajectory_of(path, machine)
        reference = ReferencePath.from_trajectory(traj)
        for controller in CONTROLLERS:
            servo = load_servo(machine, controller)

            def run(q_traj, options):
                sim = simulate(traj.t, q_traj.q, machine, controller, **options)
                return contour_errors(reference, sim.q_act, machine.kinematics)

            realistic = ensemble_actual(traj.t, machine, controller)

            linear_start = time.perf_counter()
            compensated = {1: compensate(servo, traj, iterations=1)}
            linear_time = time.perf_counter() - linear_start
            compensated[4] = compensate(servo, traj, iterations=4)
            learn_start = time.perf_counter()
            learned = compensate(servo, traj, machine_actual=realistic,
                                 learning_passes=DEFAULT_LEARNING_PASSES)
            learn_time = time.perf_counter() - learn_start
            cell = {}    # (machine, label) -> "tip max / mean, ori max / mean" reductions
            for name, options in MACHINES.items():
                before = run(traj, options)
                s0 = before.summary()
                rows.append(f"| {path} | {controller} | {name} | 0 | " +
                            " | ".join(f"{s0[k]:.4g}" for k in KEYS) + " | | |")
                commands = [("1", compensated[1])]
                if name in ("exact", "realistic"):
                    commands.append((f"up to 4 (kept {compensated[4].iterations})",
                                     compensated[4]))
                if name != "exact":
                    commands.append((f"1 + learning ({learned.learning.chosen})", learned))
                for label, result in commands:
                    after = run(result.trajectory, options)
                    s1 = after.summary()
                    red = [100 * (1 - s1[k] / s0[k]) for k in KEYS]
                    rows.append(f"| {path} | {controller} | {name} | {label} | " +
                                " | ".join(f"{s1[k]:.4g}" for k in KEYS) +
                                f" | {red[0]:.1f} / {red[1]:.1f} | {red[2]:.1f} / {red[3]:.1f} |")
                    cell[(name, label.split(" (")[0])] = (
                        f"{red[0]:.1f} / {red[1]:.1f}, {red[2]:.1f} / {red[3]:.1f}")
                    if name == "realistic" and label == "1":
                        linear = after
                    elif name == "realistic" and result is learned:
                        learned_errors = after
                if name == "realistic":
                    cells, short = [], []
                    for errors in (before, linear, learned_errors):
                        i = int(np.argmax(errors.tip))
                        cells.append(f"{1e3 * errors.tip[i]:.2f} at {where(traj, i)}")
                        short.append(f"{1e3 * errors.tip[i]:.2f} um at "
                                     f"{where(traj, i, short=True)}")
                    red = [100 * (1 - e.tip.max() / before.tip.max())
                           for e in (linear, learned_errors)]
                    places.append(f"| {path} | {controller} | " + " | ".join(cells) +
                                  f" | {red[0]:.1f} / {red[1]:.1f} | "
                                  f"{learned.learning.chosen} | "
                                  f"{learned.learning.machine_runs} runs, {learn_time:.1f} s "
                                  f"({learn_time / linear_time:.0f} x the 1-pass time) |")
                    readme_places.append(f"| {_name(path)} | {controller} | "
                                         + " | ".join(short)
                                         + f" ({learned.learning.chosen}) |")
            kept = compensated[4].iterations
            readme_rows.append(
                f"| {_name(path)} | {controller} | {cell[('exact', '1')]} | "
                f"{cell[('exact', 'up to 4')]} ({kept}) | {cell[('realistic', '1')]} | "
                f"**{cell[('realistic', '1 + learning')]}** | "
                + " | ".join(f"{cell[(m, '1')]}; {cell[(m, '1 + learning')]}"
                             for m in ("J,B +20 %", "J,B -20 %")) + " |")
    print("# Compensation, measured\n")
    print(stamp() + f" ({time.perf_counter() - start:.0f} s.)\n")
    print("Written by `scripts/measure_compensation.py`; do not edit by hand. What the "
          "compensation and the learning do: [learning](learning.md). "
          "Contour errors on the virtual machine ([method](method.md#the-virtual-machine)): "
          "tip in um, orientation in mrad; passes 0 = "
          "uncompensated, 'up to 4' = iterated linear passes, '1 + learning' = one linear pass and "
          f"{DEFAULT_LEARNING_PASSES} learning passes against the realistic machine, "
          "`compensate --ignore-limits --learn`, every choice on the worst of the five draws "
          "of the machine ensemble, with the command kept. Test paths: "
          f"{', '.join(TEST_PATHS)} (see the script).\n")
    print("| path | controller | machine | passes | tip max um | tip mean um | ori max mrad "
          "| ori mean mrad | reduction tip max / mean % | reduction ori max / mean % |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print("\n## Where the largest tip error is (realistic machine)\n")
    print("| path | controller | uncompensated: max um at | 1 pass: max um at "
          "| 1 pass + learning: max um at | reduction of the max, 1 pass / + learning % "
          "| learning kept | learning cost |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(places))
    print("\n## Summary\n")
    print("Reductions of the max / mean contour errors, tip then orientation, in %:\n")
    print("| path | controller | exact model, 1 pass | exact, up to 4 passes (passes kept) "
          "| realistic machine, 1 pass | realistic, 1 pass + learning (default) "
          "| J, B +20 %: 1 pass; + learning | J, B -20 %: 1 pass; + learning |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(readme_rows))
    print("\nWhere the largest tip error is, realistic machine:\n")
    print("| path | controller | uncompensated | 1 pass | 1 pass + learning (kept) |")
    print("|---|---|---|---|---|")
    print("\n".join(readme_places))
    print(f"\n({time.perf_counter() - start:.1f} s)", file=sys.stderr)


if __name__ == "__main__":
    args = sys.argv[1:]
    output = None
    if "--output" in args:
        at = args.index("--output")
        output = Path(args[at + 1])
        del args[at:at + 2]
    chosen = [a for a in args if not a.startswith("--")]
    if not chosen:
        chosen = list(BUILTIN_PATHS) + (list(TEST_PATHS) if "--test-paths" in args else [])
    if output is None:
        main(chosen)
    else:
        # the page is written whole at the end: a failed run leaves the old one
        page = io.StringIO()
        with contextlib.redirect_stdout(page):
            main(chosen)
        print(f"wrote {write_page(output, page.getvalue())}", file=sys.stderr)
