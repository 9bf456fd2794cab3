"""The comparison of compensation methods and controllers: the paper's Figs. 11-16 (spec
section 7) re-run on the realistic virtual machine, with each of the paper's claims measured.

For one trajectory: run the sliding-mode controller, and each linear controller (P-PI, PID)
uncompensated, with axis tracking-error pre-compensation and with contour-error
pre-compensation; measure contour errors, the spectra of the two compensation signals
(q_comp - q_ref) and the peak velocity, acceleration and jerk of the commands. This module owns
the orchestration, the numbers and the claims' answers; :mod:`precontour.reports.compare_report` draws
and writes them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from scipy import signal

from ..trajectory.builtin_paths import BUILTIN_PATHS, builtin_path
from ..compensation.precompensate import CompensationResult, compensate
from ..compensation.programmed_end import required_final_rest, with_final_rest
from ..prediction.contour import ContourErrors, ReferencePath, contour_errors
from .demo import MACHINE_MODELS
from .progress import Progress, StepCounter
from ..machine.drives import AXES, ROTARY_AXES
from ..errors import InputError, is_whole_number, plain
from ..files import check_report_folder, input_files
from ..machine.machine_file import Machine, load_machine
from ..machine.servo import load_servo
from ..simulation.virtual_machine import SimulationResult, simulate_trajectory
from ..tables import check_reference, read_trajectory
from ..trajectory.sampled import Trajectory
from ..trajectory.generate import TrajectorySummary, generate_trajectory, summarize

#: Compensation kinds, in table order.
COMPENSATIONS: tuple[str, ...] = ("none", "tracking", "contour")
#: The realistic virtual machine every run uses (discrete control, friction, feed-forward).
MACHINE_OPTIONS: dict = MACHINE_MODELS["realistic"]
#: Claim (b) compares the power of the compensation signals above this frequency. Fixed before
#: looking at the answer: the closed loops' -3 dB bandwidths are 35-80 Hz, and the signals'
#: spectra fall by three to four decades between 2 and 20 Hz, so 10 Hz splits the path's own
#: content from the compensation's fast corrections.
SPECTRUM_CUTOFF_HZ = 10.0
#: Further cut-offs reported in the spectra table, to show how the answer depends on the choice.
SPECTRUM_CUTOFFS_HZ: tuple[float, ...] = (5.0, 10.0, 20.0, 50.0)
#: Welch segment length (samples): 0.512 s at 1 kHz, about 2 Hz resolution, several segments
#: on a 2-3 s path.
WELCH_SEGMENT = 512
#: Claim (c): the paper says the commands' derivatives are "nearly unchanged"; we call a change
#: of the peak of at most this much (%) nearly unchanged.
NEARLY_UNCHANGED_PCT = 10.0
#: Spectrum signals: the five axes and the linear axes together (sum of X, Y, Z powers).
SPECTRUM_SIGNALS: tuple[str, ...] = AXES + ("XYZ",)
DERIVATIVES: tuple[tuple[str, str, str], ...] = (
    ("velocity", "mm/s", "rad/s"), ("acceleration", "mm/s^2", "rad/s^2"),
    ("jerk", "mm/s^3", "rad/s^3"))
#: Claim (a2), Fig. 11 under model error: the plant's J and B are scaled by 1 + e for each e
#: here, while sliding mode feeds the nominal model forward and the pre-compensation predicts
#: with it. 20 % is the model error docs/claims.md measures for an unidentified machine; both
#: signs, since a feed-forward law can gain or lose from either.
DEFAULT_MODEL_ERRORS: tuple[float, ...] = (0.2, -0.2)
#: Contour error metrics: (summary key, label, unit).
METRICS: tuple[tuple[str, str, str], ...] = (
    ("tip_max_um", "tip max", "um"), ("tip_mean_um", "tip mean", "um"),
    ("ori_max_mrad", "orientation max", "mrad"), ("ori_mean_mrad", "orientation mean", "mrad"))


@dataclass(frozen=True)
class CompareRun:
    """One controller following one kind of command on the realistic machine.

    Attributes
    ----------
    controller, compensation : str
        Controller name; ``"none"``, ``"tracking"`` or ``"contour"``.
    commands : Trajectory
        The axis commands sent to the drives (with the reference P, O).
    simulation : SimulationResult
    contour : ContourErrors
        Measured against the reference path.
    axis_errors : ndarray, shape (N, 5)
        Reference command minus actual position, mm and rad (what each axis misses by).
    compensation_result : CompensationResult or None
        The pre-compensation (with its predicted errors); None for ``"none"``.
    """

    controller: str
    compensation: str
    commands: Trajectory
    simulation: SimulationResult
    contour: ContourErrors
    axis_errors: np.ndarray
    compensation_result: CompensationResult | None = None


@dataclass(frozen=True)
class Spectrum:
    """Welch power spectral densities of a controller's two compensation signals.

    Attributes
    ----------
    controller : str
    f : ndarray, shape (M,)
        Frequencies, Hz.
    tracking, contour : ndarray, shape (M, 5)
        One-sided PSD of q_comp - q_ref per axis, mm^2/Hz (X, Y, Z) and rad^2/Hz (A, C).
    """

    controller: str
    f: np.ndarray
    tracking: np.ndarray
    contour: np.ndarray

    def psd(self, kind: str, name: str) -> np.ndarray:
        """PSD of signal ``name`` (an axis or ``"XYZ"``) of ``kind`` in um^2/Hz or mrad^2/Hz,
        shape (M,)."""
        values = getattr(self, kind)
        if name == "XYZ":
            return 1e6 * values[:, :3].sum(axis=1)
        return 1e6 * values[:, AXES.index(name)]

    def band_power(self, kind: str, name: str, cutoff_hz: float) -> float:
        """Mean-square content above ``cutoff_hz``: the PSD integrated over [cutoff, fs/2],
        um^2 (mrad^2 for A, C)."""
        df = self.f[1] - self.f[0]
        return float(self.psd(kind, name)[self.f >= cutoff_hz].sum() * df)

    def total_power(self, kind: str, name: str) -> float:
        """Mean-square content at all frequencies, um^2 (mrad^2)."""
        return self.band_power(kind, name, -1.0)


@dataclass(frozen=True)
class Claim:
    """One of the paper's claims and our measured answer.

    Attributes
    ----------
    key : str
        ``"a"`` ... with the controller, e.g. ``"a:p-pi-high"``.
    question : str
    verdict : str
        ``"holds"``, ``"partly holds"``, ``"does not hold"`` or ``"not measurable"`` (nothing
        to compare, e.g. all signals zero).
    lines : tuple of str
        The numbers behind the verdict, one per line.
    """

    key: str
    question: str
    verdict: str
    lines: tuple[str, ...]

    def format(self) -> str:
        return "\n".join([f"({self.key}) {self.question}", f"    -> {self.verdict.upper()}"]
                         + [f"    {line}" for line in self.lines])


@dataclass(frozen=True)
class CompareResult:
    """Everything :func:`run_compare` computed and wrote.

    Attributes
    ----------
    out_dir : Path
    machine : Machine
    source : str
        ``"built-in path 'paper'"`` or the trajectory file.
    trajectory : Trajectory
        The reference commands with the reference tool path.
    summary : TrajectorySummary
    sliding : str or None
        The sliding-mode controller's name (Fig. 11), if run.
    ppi : str or None
        The P-PI controller (Figs. 11, 14-16).
    pids : tuple of str
        PID controllers (Figs. 12-13).
    iterations : int
        Largest number of contour compensation passes.
    runs : mapping (controller, compensation) -> CompareRun
        On the plant that is exactly the machine model.
    model_error_runs : mapping (controller, compensation, model error) -> CompareRun
        Sliding mode, and P-PI uncompensated and with contour pre-compensation (the commands
        of ``runs``, compensated with the nominal model), on plants whose J and B are scaled
        by 1 + model error (claim a2).
    spectra : mapping controller -> Spectrum
        For each linear controller.
    contour_rows, spectrum_rows, peak_rows, model_error_rows : list of dict
        The tables (see :func:`contour_rows`, :func:`spectrum_rows`, :func:`peak_rows`,
        :func:`model_error_rows`).
    claims : tuple of Claim
    files : tuple of Path
        Every file written, ``index.html`` last.
    timings : dict
        Wall time (s): ``"compute"``, ``"report"``, ``"total"``.
    """

    out_dir: Path
    machine: Machine
    source: str
    trajectory: Trajectory
    summary: TrajectorySummary
    sliding: str | None
    ppi: str | None
    pids: tuple[str, ...]
    iterations: int
    runs: Mapping[tuple[str, str], CompareRun]
    spectra: Mapping[str, Spectrum]
    model_error_runs: Mapping[tuple[str, str, float], CompareRun] = field(default_factory=dict)
    contour_rows: list = field(default_factory=list)
    spectrum_rows: list = field(default_factory=list)
    peak_rows: list = field(default_factory=list)
    model_error_rows: list = field(default_factory=list)
    claims: tuple[Claim, ...] = ()
    files: tuple[Path, ...] = ()
    timings: dict = field(default_factory=dict)

    @property
    def linear(self) -> tuple[str, ...]:
        """The linear controllers, P-PI first."""
        return ((self.ppi,) if self.ppi else ()) + self.pids

    def run(self, controller: str, compensation: str = "none") -> CompareRun:
        return self.runs[(controller, compensation)]

    @property
    def model_errors(self) -> tuple[float, ...]:
        """The model errors of :attr:`model_error_runs`, in run order."""
        return tuple(dict.fromkeys(e for _, _, e in self.model_error_runs))

    def claim(self, key: str) -> Claim:
        for claim in self.claims:
            if claim.key == key:
                return claim
        raise KeyError(key)


# --------------------------------------------------------------------------------------------
# Measurements
# --------------------------------------------------------------------------------------------

def compensation_spectrum(controller: str, reference: Trajectory, tracking: Trajectory,
                          contour: Trajectory, *, nperseg: int = WELCH_SEGMENT) -> Spectrum:
    """Welch PSDs (Hann window, half overlap, mean removed per segment) of the compensation
    signals ``tracking.q - reference.q`` and ``contour.q - reference.q``."""
    fs = 1.0 / reference.ts
    n = min(nperseg, reference.n_samples)
    f, p_track = signal.welch(tracking.q - reference.q, fs=fs, nperseg=n, axis=0)
    _, p_cont = signal.welch(contour.q - reference.q, fs=fs, nperseg=n, axis=0)
    return Spectrum(controller=controller, f=f, tracking=p_track, contour=p_cont)


def command_derivatives(q: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk of sampled commands by backward differences at the
    sample period (what the drives receive), shapes (N-1, 5), (N-2, 5), (N-3, 5)."""
    v = np.diff(q, axis=0) / ts
    a = np.diff(v, axis=0) / ts
    return v, a, np.diff(a, axis=0) / ts


def contour_rows(result: CompareResult) -> list[dict]:
    """Measured (and, for linear controllers, predicted) contour errors of every run: keys
    ``controller, compensation, passes`` and ``tip_max_um ... ori_mean_mrad``, plus
    ``predicted_<metric>`` (None for the sliding-mode controller)."""
    rows = []
    for (name, kind), run in result.runs.items():
        row = dict(controller=name, compensation=kind,
                   passes=None if run.compensation_result is None
                   else run.compensation_result.iterations)
        row.update(run.contour.summary())
        predicted = _predicted(result, name, kind)
        for key, _, _ in METRICS:
            row[f"predicted_{key}"] = None if predicted is None else predicted[key]
        rows.append(row)
    return rows


def _predicted(result: CompareResult, name: str, kind: str) -> dict | None:
    if kind == "none":
        comp = next((result.runs[(name, k)].compensation_result for k in COMPENSATIONS[1:]
                     if (name, k) in result.runs), None)
        return None if comp is None else comp.before.summary()
    return result.runs[(name, kind)].compensation_result.after.summary()


def model_error_rows(result: CompareResult) -> list[dict]:
    """Measured contour errors of sliding mode and P-PI (uncompensated, contour
    pre-compensated with the nominal model) on the plant that is the model (``model_error``
    0) and on the plants of :attr:`CompareResult.model_error_runs`: keys ``model_error_pct,
    inertia_scale, damping_scale, controller, compensation`` and ``tip_max_um ...
    ori_mean_mrad``; empty without sliding mode, P-PI or model errors."""
    if not (result.sliding and result.ppi and result.model_error_runs):
        return []
    kinds = ((result.sliding, "none"), (result.ppi, "none"), (result.ppi, "contour"))
    rows = []
    for error in (0.0,) + result.model_errors:
        for name, kind in kinds:
            run = (result.runs[(name, kind)] if error == 0.0
                   else result.model_error_runs[(name, kind, error)])
            rows.append(dict(model_error_pct=100.0 * error, inertia_scale=1.0 + error,
                             damping_scale=1.0 + error, controller=name, compensation=kind,
                             **run.contour.summary()))
    return rows


def spectrum_rows(result: CompareResult) -> list[dict]:
    """Power of each compensation signal above each cut-off of :data:`SPECTRUM_CUTOFFS_HZ`:
    keys ``controller, signal, unit, cutoff_hz, tracking_power, contour_power, ratio``
    (contour / tracking) and ``tracking_share_pct, contour_share_pct`` (of each signal's total
    power)."""
    rows = []
    for name, spectrum in result.spectra.items():
        for sig in SPECTRUM_SIGNALS:
            unit = "mrad^2" if sig in ROTARY_AXES else "um^2"
            totals = {k: spectrum.total_power(k, sig) for k in ("tracking", "contour")}
            for cutoff in SPECTRUM_CUTOFFS_HZ:
                power = {k: spectrum.band_power(k, sig, cutoff) for k in ("tracking", "contour")}
                rows.append(dict(
                    controller=name, signal=sig, unit=unit, cutoff_hz=cutoff,
                    tracking_power=power["tracking"], contour_power=power["contour"],
                    ratio=_ratio(power["contour"], power["tracking"]),
                    tracking_share_pct=_share(power["tracking"], totals["tracking"]),
                    contour_share_pct=_share(power["contour"], totals["contour"])))
    return rows


def peak_rows(result: CompareResult) -> list[dict]:
    """Peak |velocity|, |acceleration| and |jerk| of each axis command, reference vs
    pre-compensated (both methods) for each linear controller: keys ``controller,
    compensation, axis, quantity, unit, reference, compensated, change_pct``."""
    ts = result.trajectory.ts
    reference = [np.abs(d).max(axis=0) for d in command_derivatives(result.trajectory.q, ts)]
    rows = []
    for name in result.linear:
        for kind in COMPENSATIONS[1:]:
            peaks = [np.abs(d).max(axis=0)
                     for d in command_derivatives(result.run(name, kind).commands.q, ts)]
            for (quantity, lin_unit, rot_unit), ref, comp in zip(DERIVATIVES, reference, peaks):
                for i, axis in enumerate(AXES):
                    rows.append(dict(controller=name, compensation=kind, axis=axis,
                                     quantity=quantity,
                                     unit=rot_unit if axis in ROTARY_AXES else lin_unit,
                                     reference=float(ref[i]), compensated=float(comp[i]),
                                     change_pct=_change(float(comp[i]), float(ref[i]))))
    return rows


def _ratio(a: float, b: float) -> float:
    """a / b; inf if only b is zero, nan if both are."""
    return a / b if b > 0 else float("inf") if a > 0 else float("nan")


def _share(part: float, whole: float) -> float:
    return 100.0 * part / whole if whole > 0 else 0.0


def _change(new: float, old: float) -> float:
    """100 (new / old - 1) %."""
    return 100.0 * (_ratio(new, old) - 1.0)


# --------------------------------------------------------------------------------------------
# Claims
# --------------------------------------------------------------------------------------------

def _verdict(wins: Sequence[bool]) -> str:
    if not wins:
        return "not measurable"
    return "holds" if all(wins) else "does not hold" if not any(wins) else "partly holds"


def _g(value: float, digits: int = 4) -> str:
    """``digits`` significant digits, without the bare trailing point of ``#g`` (``2383.``)."""
    return f"{value:#.{digits}g}".rstrip(".")


def _versus(label: str, unit: str, a_name: str, a: float, b_name: str, b: float) -> str:
    """``tip max: tracking 21.21 um, contour 8.027 um: contour 62.2 % lower``."""
    change = _change(b, a)
    word = "lower" if change < 0 else "higher"
    return (f"{label}: {a_name} {_g(a)} {unit}, {b_name} {_g(b)} {unit}: "
            f"{b_name} {abs(change):.1f} % {word}")


def _compare_claim(key, question, a_name, a_summary, b_name, b_summary, *,
                   b_lower: bool = True) -> Claim:
    """Claim that ``b`` has smaller (``b_lower``) or larger contour errors than ``a``, on the
    four metrics."""
    lines, wins = [], []
    for metric, label, unit in METRICS:
        lines.append(_versus(label, unit, a_name, a_summary[metric], b_name, b_summary[metric]))
        wins.append((b_summary[metric] < a_summary[metric]) == b_lower)
    return Claim(key=key, question=question, verdict=_verdict(wins), lines=tuple(lines))


def make_claims(result: CompareResult) -> tuple[Claim, ...]:
    """The paper's claims (spec section 7, Figs. 11-16) answered from the result's numbers."""
    claims = []
    summary = {key: run.contour.summary() for key, run in result.runs.items()}
    if result.ppi:
        claims.append(_compare_claim(
            f"a0:{result.ppi}", f"Under P-PI ({result.ppi}), does axis tracking-error "
            "pre-compensation make the contour errors worse than no compensation "
            "(paper Figs. 14-15)?", "none", summary[(result.ppi, "none")],
            "tracking", summary[(result.ppi, "tracking")], b_lower=False))
    for name in result.linear:
        kind = "P-PI" if name == result.ppi else "PID"
        claims.append(_compare_claim(
            f"a:{name}", f"Under {kind} ({name}), does contour-error pre-compensation give "
            "smaller contour errors than axis tracking-error pre-compensation "
            "(paper Figs. 12, 15)?", "tracking", summary[(name, "tracking")],
            "contour", summary[(name, "contour")]))
    if result.sliding and result.ppi:
        claims.append(_compare_claim(
            f"a1:{result.ppi}", f"Does P-PI ({result.ppi}) with contour pre-compensation give "
            f"smaller contour errors than the sliding-mode controller ({result.sliding}) "
            "(paper Fig. 11), on a plant that is exactly the machine model?", "sliding mode",
            summary[(result.sliding, "none")], "P-PI+contour", summary[(result.ppi, "contour")]))
    if result.sliding and result.ppi and result.model_error_runs:
        claims.append(_model_error_claim(result))
    rows = {(r["controller"], r["signal"], r["cutoff_hz"]): r for r in result.spectrum_rows}
    for name in result.linear:
        lines, wins = [], []
        for sig in SPECTRUM_SIGNALS:
            r = rows[(name, sig, SPECTRUM_CUTOFF_HZ)]
            if r["tracking_power"] == r["contour_power"] == 0.0:
                lines.append(f"{sig}: both compensation signals are zero above "
                             f"{SPECTRUM_CUTOFF_HZ:g} Hz (left out of the verdict)")
                continue
            wins.append(r["contour_power"] < r["tracking_power"])
            lines.append(f"{sig}: power above {SPECTRUM_CUTOFF_HZ:g} Hz: tracking "
                         f"{_g(r['tracking_power'])} {r['unit']} "
                         f"({r['tracking_share_pct']:.2f} % of its total), contour "
                         f"{_g(r['contour_power'])} {r['unit']} "
                         f"({r['contour_share_pct']:.2f} %): ratio contour/tracking "
                         f"{_g(r['ratio'], 3)}")
        others = ", ".join(f"{c:g} Hz {_g(rows[(name, 'XYZ', c)]['ratio'], 3)}"
                           for c in SPECTRUM_CUTOFFS_HZ if c != SPECTRUM_CUTOFF_HZ)
        lines.append(f"XYZ ratio contour/tracking at other cut-offs: {others}")
        claims.append(Claim(
            key=f"b:{name}", question=f"Under {name}, does the contour compensation signal "
            f"have less high-frequency content (power above {SPECTRUM_CUTOFF_HZ:g} Hz) than "
            "the tracking compensation signal (paper Fig. 13)?",
            verdict=_verdict(wins), lines=tuple(lines)))
    for name in result.linear:
        lines, wins = [], []
        for quantity, _, _ in DERIVATIVES:
            cells = [r for r in result.peak_rows if r["controller"] == name
                     and r["compensation"] == "contour" and r["quantity"] == quantity]
            # nan (zero peak before and after) counts as unchanged, inf (from zero) does not
            wins += [not abs(r["change_pct"]) > NEARLY_UNCHANGED_PCT for r in cells]
            lines.append(f"peak {quantity} change: " + ", ".join(
                f"{r['axis']} {r['change_pct']:+.1f} %" for r in cells))
        worst = max((r for r in result.peak_rows if r["controller"] == name
                     and r["compensation"] == "contour"),
                    key=lambda r: -1.0 if np.isnan(r["change_pct"]) else abs(r["change_pct"]))
        lines.append(f"largest: {worst['quantity']} of {worst['axis']}, "
                     f"{_g(worst['reference'])} -> {_g(worst['compensated'])} "
                     f"{worst['unit']} ({worst['change_pct']:+.1f} %)")
        claims.append(Claim(
            key=f"c:{name}", question=f"Under {name}, are the peak velocity, acceleration and "
            "jerk of the axis commands nearly unchanged (within "
            f"{NEARLY_UNCHANGED_PCT:g} %) by contour pre-compensation (paper Fig. 16)?",
            verdict=_verdict(wins), lines=tuple(lines)))
    return tuple(claims)


def _model_error_claim(result: CompareResult) -> Claim:
    """Claim a2: Fig. 11's ranking when the plant's J and B are off the model. The paper's
    Fig. 11 was measured on a real machine, whose drives are never exactly the model that
    sliding mode feeds forward (J X'', B x') and that the pre-compensation predicts with; on
    the exact model sliding mode's feed-forward alone tracks to sampling and friction
    transients (claim a1)."""
    lines, wins = [], []
    for error in result.model_errors:
        sliding = result.model_error_runs[(result.sliding, "none", error)].contour.summary()
        ppi = result.model_error_runs[(result.ppi, "contour", error)].contour.summary()
        for metric, label, unit in METRICS:
            lines.append(f"J, B x{1 + error:g}: " + _versus(label, unit, "sliding mode",
                                                           sliding[metric], "P-PI+contour",
                                                           ppi[metric]))
            wins.append(ppi[metric] < sliding[metric])
    errors = ", ".join(f"{100 * e:+g} %" for e in result.model_errors)
    return Claim(key=f"a2:{result.ppi}", question=(
        f"With the plant's inertia J and damping B off the machine model by {errors} (as on a "
        f"real machine; both controllers use the nominal model), does P-PI ({result.ppi}) with "
        f"contour pre-compensation give smaller contour errors than the sliding-mode "
        f"controller ({result.sliding}) (paper Fig. 11)?"),
        verdict=_verdict(wins), lines=tuple(lines))


# --------------------------------------------------------------------------------------------
# Orchestration
# --------------------------------------------------------------------------------------------

def report_file_names(sliding: str | None, ppi: str | None, pids: Sequence[str],
                      model_errors: Sequence[float] = DEFAULT_MODEL_ERRORS) -> dict[str, str]:
    """Names of the files the comparison's report writes, keyed by role (figures ``fig11``
    ... ``fig16``, possibly one per controller as ``fig12:<name>``; tables; ``compare.md``;
    ``index.html`` last), for the given controllers and model errors (claim a2)."""
    names = {}
    if sliding and ppi:
        names["fig11"] = "fig11_contour_sliding_mode_vs_ppi.png"
        if model_errors:
            names["fig11:model-error"] = "fig11_contour_sliding_mode_vs_ppi_model_error.png"
            names["model-error.csv"] = "model_error.csv"
    for name in pids:
        names[f"fig12:{name}"] = f"fig12_contour_tracking_vs_contour_{name}.png"
        names[f"fig13:{name}"] = f"fig13_compensation_spectra_{name}.png"
    if ppi:
        names["fig14"] = f"fig14_axis_errors_{ppi}.png"
        names["fig15"] = f"fig15_contour_{ppi}.png"
    if ppi or pids:
        names["fig16"] = "fig16_x_command_derivatives.png"
    names.update({"contour.csv": "contour_errors.csv", "spectra.csv": "compensation_spectra.csv",
                  "peaks.csv": "command_peaks.csv", "claims.csv": "claims.csv",
                  "compare.md": "compare.md", "index.html": "index.html"})
    return names


def compute_compare(out_dir: str | Path, *, builtin: str | None = None,
                trajectory: str | Path | Trajectory | None = None,
                machine: str | Path | Machine = "zhang2013", iterations: int = 1,
                sliding: str | None = "smc", ppi: str | None = "p-pi-high",
                pids: Sequence[str] = ("pid-high", "pid-low"),
                model_errors: Sequence[float] = DEFAULT_MODEL_ERRORS,
                progress: Progress | None = None) -> CompareResult:
    """Compare controllers and compensation methods on the realistic virtual machine (the
    paper's Figs. 11-16 and the claims' measured answers); the report folder is written by
    :func:`precontour.reports.compare_report.run_compare`.

    Parameters
    ----------
    out_dir : str or Path
        Report folder; created if missing. Only the report's own files are overwritten.
    builtin : str, optional
        Built-in path name (default ``"paper"`` when ``trajectory`` is not given).
    trajectory : str, Path or Trajectory, optional
        Trajectory file (``t,X..C`` and the reference ``Px..Ok``), sampled at the machine's
        servo period, or a Trajectory.
    machine : str, Path or Machine
    iterations : int
        Largest number of contour pre-compensation passes (1 = the paper's single pass). The
        tracking baseline is always the paper's single pass. The first pass is applied even if
        it does not improve the prediction, so that each method is measured as it is.
    sliding, ppi : str or None
        Sliding-mode and P-PI controller names (None: leave out their figures and claims).
    pids : sequence of str
        PID (linear) controller names.
    model_errors : sequence of float
        For claim a2 (Fig. 11 under model error): sliding mode and P-PI (uncompensated and
        pre-compensated with the nominal model) also run on plants whose J and B are scaled by
        1 + e for each e (fractions, > -1, nonzero); empty to leave it out.
    progress : callable, optional
        ``progress(done, total, message)`` before each step.

    Returns
    -------
    CompareResult
        The result, without report files (:func:`~precontour.reports.compare_report.
        run_compare` writes them, as its own step of ``progress``).
    """
    start = time.perf_counter()
    pids = tuple(pids)
    if not is_whole_number(iterations) or iterations < 1:
        raise InputError(f"iterations must be a whole number >= 1, got {plain(iterations)!r}",
                         field="iterations")
    names = ((sliding,) if sliding else ()) + ((ppi,) if ppi else ()) + pids
    if not names:
        raise InputError("no controller to compare", field="controllers")
    if len(set(names)) != len(names):
        raise InputError(f"a controller is named twice: {', '.join(names)}",
                         field="controllers")
    model_errors = _check_model_errors(model_errors) if sliding and ppi else ()
    machine_file = machine
    if not isinstance(machine, Machine):
        machine = load_machine(machine)
    controllers = {name: machine.controller(name) for name in names}
    for name in ((ppi,) if ppi else ()) + pids:
        if not controllers[name].is_linear:
            raise InputError(f"controller {name!r} is not linear: it cannot be "
                             "pre-compensated", field="controllers")
    out_dir = check_report_folder(
        out_dir, report_file_names(sliding, ppi, pids, model_errors).values(),
        inputs=input_files(None if isinstance(trajectory, Trajectory) else trajectory,
                           None if isinstance(machine_file, Machine) else machine_file),
        what="comparison")
    traj, source = _load_source(builtin, trajectory, machine)

    linear = ((ppi,) if ppi else ()) + pids
    if linear:
        # the final rest the slowest compensated loop needs to end at the programmed end point
        # (every command judged on the same plan)
        traj = with_final_rest(traj, max(required_final_rest(
            machine.error_models(controllers[name])) for name in linear))
    total = (1 if sliding else 0) + 5 * len(linear) + 3 * len(model_errors)
    step = StepCounter(progress, total)

    reference = ReferencePath.from_trajectory(traj)

    def measure(name, kind, commands, comp=None, model_error=0.0) -> CompareRun:
        plant = (f"the realistic machine with J, B x{1 + model_error:g}" if model_error
                 else "the realistic machine")
        step(f"{name}: {kind} compensation on {plant}"
             if kind != "none" else f"{name}: uncompensated on {plant}")
        sim = simulate_trajectory(commands, machine, name, **MACHINE_OPTIONS,
                                  inertia_scale=1.0 + model_error,
                                  damping_scale=1.0 + model_error)
        return CompareRun(controller=name, compensation=kind, commands=commands,
                          simulation=sim,
                          contour=contour_errors(reference, sim.q_act, machine.kinematics),
                          axis_errors=traj.q - sim.q_act, compensation_result=comp)

    runs, spectra = {}, {}
    if sliding:
        runs[(sliding, "none")] = measure(sliding, "none", traj)
    for name in linear:
        servo = load_servo(machine, controllers[name])
        runs[(name, "none")] = measure(name, "none", traj)
        comps = {}
        for kind, passes in (("tracking", 1), ("contour", iterations)):
            step(f"{name}: {kind} pre-compensation")
            comps[kind] = compensate(servo, traj, method=kind,
                                     iterations=passes, min_passes=1, reference=reference)
            runs[(name, kind)] = measure(name, kind, comps[kind].trajectory, comps[kind])
        spectra[name] = compensation_spectrum(name, traj, comps["tracking"].trajectory,
                                              comps["contour"].trajectory)
    model_error_runs = {}
    for error in model_errors:
        for name, kind in ((sliding, "none"), (ppi, "none"), (ppi, "contour")):
            exact = runs[(name, kind)]
            model_error_runs[(name, kind, error)] = measure(
                name, kind, exact.commands, exact.compensation_result, model_error=error)
    computed = time.perf_counter()
    result = CompareResult(out_dir=out_dir, machine=machine, source=source, trajectory=traj,
                           summary=summarize(traj, machine), sliding=sliding, ppi=ppi,
                           pids=pids, iterations=iterations, runs=runs, spectra=spectra,
                           model_error_runs=model_error_runs)
    result = replace(result, contour_rows=contour_rows(result),
                     spectrum_rows=spectrum_rows(result), peak_rows=peak_rows(result),
                     model_error_rows=model_error_rows(result))
    result = replace(result, claims=make_claims(result),
                     timings={"compute": computed - start})
    return result


def _check_model_errors(model_errors: Sequence[float]) -> tuple[float, ...]:
    errors = []
    for error in model_errors:
        if isinstance(error, bool) or not isinstance(error, (int, float, np.floating)) \
                or not np.isfinite(error) or error <= -1.0 or error == 0.0:
            raise InputError(f"model error must be a nonzero fraction above -1 (J and B are "
                             f"scaled by 1 + error), got {plain(error)!r}",
                             field="model_errors")
        errors.append(float(error))
    if len(set(errors)) != len(errors):
        raise InputError(f"a model error is given twice: {errors}", field="model_errors")
    return tuple(errors)


def _load_source(builtin, trajectory, machine: Machine) -> tuple[Trajectory, str]:
    if builtin is not None and trajectory is not None:
        raise InputError("give a built-in path or a trajectory, not both", field="builtin")
    if trajectory is None:
        builtin = "paper" if builtin is None else builtin
        if builtin not in BUILTIN_PATHS:
            raise InputError(f"unknown built-in path {builtin!r}; choose one of "
                             f"{', '.join(BUILTIN_PATHS)}", field="builtin")
        traj = generate_trajectory(builtin_path(builtin), machine, ts=machine.servo_period)
        return traj, f"built-in path '{builtin}'"
    if isinstance(trajectory, Trajectory):
        traj, source = trajectory, "trajectory"
    else:
        source = str(trajectory)
        traj = read_trajectory(trajectory, axis_names=machine.axis_names)
    if not traj.has_reference:
        raise InputError("the comparison needs the reference tool path columns "
                         "Px,Py,Pz,Oi,Oj,Ok (write the trajectory with 'precontour "
                         "trajectory')", source=source, field="Px")
    if not machine.at_servo_period(traj.ts):
        raise InputError(f"sample period {traj.ts:.9g} s differs from the machine's servo "
                         f"period {machine.servo_period:.9g} s", source=source, field="t")
    if not isinstance(trajectory, Trajectory):
        check_reference(traj, machine.kinematics, source=source)
    return traj, source
