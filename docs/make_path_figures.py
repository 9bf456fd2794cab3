"""Draw each built-in path: the tool tip in 3-D with tool orientations, and the five axis
commands over time on the zhang2013 machine (like Fig. 8 of Zhang et al. 2013).

Run from the repository root:  python docs/make_path_figures.py  -> docs/paths/<name>.png
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from precontour import load_machine  # noqa: E402
from precontour.trajectory.builtin_paths import BUILTIN_PATHS, builtin_path  # noqa: E402
from precontour.trajectory.generate import generate_trajectory, summarize  # noqa: E402

OUT = Path(__file__).resolve().parent / "paths"


def draw(name: str, machine) -> Path:
    tr = generate_trajectory(builtin_path(name), machine)
    summary = summarize(tr, machine)
    fig = plt.figure(figsize=(12, 6.5))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    P, O = tr.P, tr.O
    ax3.plot(*P.T, color="k", lw=1.5, label="tool tip")
    every = max(1, tr.n_samples // 40)
    tail = P[::every]
    head = 15.0 * O[::every]
    ax3.quiver(*tail.T, *head.T, color="tab:blue", lw=0.8, arrow_length_ratio=0.15,
               label="tool orientation (15 mm)")
    ax3.scatter(*P[0], color="tab:green", s=30, label="start")
    ax3.set_xlabel("x (mm)")
    ax3.set_ylabel("y (mm)")
    ax3.set_zlabel("z (mm)")
    cloud = np.vstack([P, P + 15 * O])
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    # Equal scales on all three axes, so orientations look as they are.
    span = np.maximum(hi - lo, 0.15 * (hi - lo).max())
    mid = 0.5 * (lo + hi)
    ax3.set_xlim(mid[0] - span[0] / 2, mid[0] + span[0] / 2)
    ax3.set_ylim(mid[1] - span[1] / 2, mid[1] + span[1] / 2)
    ax3.set_zlim(mid[2] - span[2] / 2, mid[2] + span[2] / 2)
    ax3.set_box_aspect(span)
    ax3.legend(loc="upper left", fontsize=8)
    ax3.set_title(f"built-in path '{name}' (workpiece frame)")

    labels = ["X (mm)", "Y (mm)", "Z (mm)", "A (rad)", "C (rad)"]
    for i, label in enumerate(labels):
        ax = fig.add_subplot(5, 2, 2 * i + 2)
        ax.plot(tr.t, tr.q[:, i], lw=1.2)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if i < 4:
            ax.tick_params(labelbottom=False)
    ax.set_xlabel("time (s)")
    fig.suptitle(f"{name}: {summary.duration:.3f} s, peak feed {summary.peak_feed:.1f} mm/s "
                 f"on {machine.name} (L_ac = {machine.kinematics.L_ac:g} mm, "
                 f"L_ty = {machine.kinematics.L_ty:g} mm)")
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    print(f"{path}\n{summary}\n")
    return path


if __name__ == "__main__":
    machine = load_machine("zhang2013")
    for name in BUILTIN_PATHS:
        draw(name, machine)
