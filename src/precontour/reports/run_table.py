"""The end-of-run table of ``precontour run`` (:meth:`~precontour.workflow.RunResult.table`):
the contour errors before and after, on the draws and on the machine file's machine, where
they are largest, the lines worse, learning, the duration and its slow-downs, the blocks
written and which output to run on LinuxCNC."""

from __future__ import annotations

from ..compensation.blocks import MARGINS
from ..workflow.result import RunResult

__all__ = ["run_table"]


def run_table(result: RunResult) -> str:
    """The end-of-run table of ``result``, as ``precontour run`` prints it."""
    rows = [("predicted", "before", result.predicted_before),
            ("predicted", "after", result.predicted_after),
            ("simulated", "before", result.simulated_before),
            ("simulated", "after", result.simulated_after)]
    lines = [f"{'contour errors':<22}{'tip max':>10}{'tip mean':>10}{'ori max':>10}"
             f"{'ori mean':>10}",
             f"{'':<22}{'um':>10}{'um':>10}{'mrad':>10}{'mrad':>10}"]
    where = result.place
    # the draws first: where an axis stops under friction one exact machine's answer is
    # decided by nanometres, so the median and the worst draw are the result (issue 42)
    if result.draws is not None:
        lines += result.draws.table(where, learned=result.limited.result.learning is not None)
        lines.append("on the machine file's machine alone (draw 0), predicted and "
                     "simulated:")
    for kind, when, errors in rows:
        s = errors.summary()
        lines.append(f"{kind + ' ' + when:<22}{s['tip_max_um']:10.3f}{s['tip_mean_um']:10.3f}"
                     f"{s['ori_max_mrad']:10.4f}{s['ori_mean_mrad']:10.4f}")
    for label, before, after in (("tip", result.simulated_before.tip,
                                  result.simulated_after.tip),
                                 ("orientation", result.simulated_before.orientation,
                                  result.simulated_after.orientation)):
        lines.append(f"simulated {label} reduction: max {_reduction(before.max(), after.max())}, "
                     f"mean {_reduction(before.mean(), after.mean())}")
    lines.append("largest simulated errors, where:")
    lines += ["  " + largest.format() for largest in result.largest_errors()]
    worse = result.worse_lines()
    if worse:
        lines.append(f"compensated worse than uncompensated on {len(worse)} {where}(s) "
                     f"(beyond {MARGINS}), simulated, largest first:")
        lines += ["  " + w.format(where) for w in worse[:5]]
        if len(worse) > 5:
            lines.append(f"  ... and {len(worse) - 5} more")
    else:
        lines.append(f"no {where} worse than uncompensated (beyond {MARGINS}), simulated")
    duration = result.commands.duration
    planned = result.planned.duration - result.final_rest_added
    slow = result.limited.slowdowns
    learning = result.limited.result.learning
    if learning is not None:
        lines.append(f"learned against the virtual machine within the limits "
                     f"({learning.draws} draw(s), {learning.machine_runs} runs): kept "
                     f"{learning.chosen}")
        fallback = learning.fallback
        if fallback is not None and fallback.blocks:
            lines.append(f"  where the learned command would be worse than uncompensated "
                         f"on a draw, it fell back in {len(fallback.blocks)} block(s):")
            lines.extend("    " + b.format() for b in fallback.blocks[:10])
            if len(fallback.blocks) > 10:
                lines.append(f"    ... and {len(fallback.blocks) - 10} more blocks")
    lines.append(f"duration {duration:.3f} s (planned {planned:.3f} s"
                 + (f"; +{result.final_rest_added:.3f} s of final rest, for the corrections "
                    "to taper to zero at the programmed end point"
                    if result.final_rest_added > 0 else "")
                 + (f"; slowed in {len(slow)} window(s), +{result.limited.added_time:.3f} s"
                    if slow else "; not slowed") + ")")
    for s in slow[:10]:
        lines.append("  slowed " + s.format())
    if len(slow) > 10:
        lines.append(f"  ... and {len(slow) - 10} more windows")
    left_out = result.limited.uncompensated
    if left_out:
        lines.append(f"compensation left out in {len(left_out)} window(s) where slowing down "
                     f"to {100 * result.limited.min_speed:g} % of the planned speed or "
                     "more could not keep the limits (the planned commands there): "
                     + ", ".join(f"t = {a:.3f}-{b:.3f} s" for a, b in left_out[:10])
                     + (" ..." if len(left_out) > 10 else ""))
    kinks = result.limited.kinks
    if kinks:
        lines.append(f"kinks of the corrections smoothed in {len(kinks)} window(s) (corners at "
                     "stops: the commands there blend into tracking-error "
                     "pre-compensation): " + ", ".join(f"t = {a:.3f}-{b:.3f} s"
                                                      for a, b in kinks[:5])
                     + (" ..." if len(kinks) > 5 else ""))
    smoothed = result.limited.smoothed
    if smoothed:
        lines.append(f"corrections smoothed instead of slowed down in {len(smoothed)} "
                     "window(s) (they broke a limit; blended into tracking-error "
                     "pre-compensation, predicted no worse there): "
                     + ", ".join(f"t = {a:.3f}-{b:.3f} s" for a, b in smoothed[:5])
                     + (" ..." if len(smoothed) > 5 else ""))
    lines.append(f"blocks written {result.program.n_blocks} (tolerance "
                 f"{result.tolerance[0]:g} mm, {result.tolerance[3]:g} rad; "
                 f"{result.commands.n_samples} samples at {result.commands.ts * 1e3:g} ms)")
    lines.append(result.linuxcnc_line())
    if result.feed is not None:
        lines.append(result.feed.table())
    return "\n".join(lines)


def _reduction(before: float, after: float) -> str:
    return f"{100 * (1 - after / before):.1f} %" if before > 0 else "-"
