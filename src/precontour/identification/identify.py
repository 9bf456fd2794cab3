"""From a servo log and a base machine to an identified machine file.

Each axis in the log that moves gets its closed loop x/X (:mod:`.tf_fit`), written as one
axis of a controller of type ``tf``; an axis that never moves (or is not in the log) keeps the
base controller's closed loop, with a one-line note saying so. When the log has motor currents,
the drive's J, B and friction (:mod:`.physical`) replace the base machine's in the drive table.
When every identified axis got them, the ``tf`` table names the base controller as ``base``:
with those drives it is the virtual machine that compensation learns against (a transfer
function has no friction).

Inside, axes are keyed by the library's q slots (``X Y Z A C``), as the log is; everything a
user reads -- the notes, the machine file's tables and header, the summary rows -- names the
base machine's letters (``B`` in slot A of a B-C machine, ``B`` in slot C of an A-B one).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..machine.controllers import Controller, closed_loop_bandwidth, is_closed_loop
from ..machine.drives import AXES, LinearErrorModel
from ..machine.machine_file import Machine, machine_file_text, parse_machine
from .physical import PhysicalParameters, identify_physical
from .servo_log import ServoLog
from .tf_fit import AxisIdentification, NotIdentifiable, friction_guard_for, identify_axis

#: Largest order accepted by ``order=N``.
MAX_ORDER = 10


@dataclass(frozen=True)
class IdentificationResult:
    """What :func:`identify` found; ``machine`` is the identified machine, ``text`` its file."""

    log: ServoLog
    base: Machine
    base_controller: Controller
    name: str
    axes: dict
    notes: dict
    physical: dict
    machine: Machine
    text: str
    base_models: tuple = field(default=())

    @property
    def axis_names(self) -> tuple[str, ...]:
        """The machine's five axis letters in q order (``Machine.axis_names``)."""
        return self.base.axis_names

    def letter(self, axis: str) -> str:
        """The machine's letter of q slot ``axis`` (a key of ``axes``, ``physical``, ``log``)."""
        return self.axis_names[AXES.index(axis)]

    def identified_models(self) -> tuple[LinearErrorModel, ...]:
        return self.machine.error_models(self.name)

    def summary_rows(self) -> list[dict]:
        """Per axis: order, fit %, held-out %, bandwidths (Hz), poles (rad/s); ``axis`` is the
        machine's letter, ``slot`` the q slot."""
        rows = []
        models = self.identified_models()
        for i, axis in enumerate(AXES):
            base = self.base_models[i]
            row = dict(axis=self.axis_names[i], slot=axis, identified=axis in self.axes, base_bw=_bandwidth(base),
                       base_poles=base.poles, bw=_bandwidth(models[i]), poles=models[i].poles)
            if axis in self.axes:
                fit: AxisIdentification = self.axes[axis]
                row.update(order=fit.order, fit_pct=fit.fit_pct, holdout_pct=fit.holdout_pct)
            rows.append(row)
        return rows


def _bandwidth(model: LinearErrorModel) -> float:
    try:
        return closed_loop_bandwidth(model)
    except Exception:  # a closed loop that never falls below -3 dB: report it as unknown
        return float("nan")


def parse_order(order) -> int | str:
    if order in (None, "auto"):
        return "auto"
    try:
        value = int(order)
    except (TypeError, ValueError):
        raise InputError(f"must be 'auto' or a whole number 1..{MAX_ORDER}, got {order!r}",
                         field="order") from None
    if not 1 <= value <= MAX_ORDER:
        raise InputError(f"must be 'auto' or a whole number 1..{MAX_ORDER}, got {order!r}",
                         field="order")
    return value


def default_base_controller(machine: Machine) -> Controller:
    """The first linear controller of the machine (the one the log was recorded with, usually)."""
    for controller in machine.controllers.values():
        if controller.is_linear:
            return controller
    raise InputError("the base machine has no linear controller to keep for axes the log "
                     "cannot identify", source=machine.source)


def identify(log: ServoLog, base: Machine, base_data: dict, *, name: str = "identified",
             order="auto", base_controller: str | None = None) -> IdentificationResult:
    """Identify every moving axis of ``log``; build the machine file text and parse it back.

    ``base_data`` is the base machine's raw TOML data (:func:`~precontour.machine.machine_file.machine_data`).
    """
    order = parse_order(order)
    if not name or not all(c.isalnum() or c in "-_" for c in name):
        raise InputError(f"controller name must be letters, digits, '-' or '_', got {name!r}",
                         field="name")
    ctrl = default_base_controller(base) if base_controller is None else base.controller(base_controller)
    base_models = base.error_models(ctrl)
    ts = log.period
    if not base.at_servo_period(ts):
        # Not an error: the model is continuous; say it in the notes.
        period_note = (f"log sample period {ts * 1e3:.6g} ms differs from the machine's servo "
                       f"period {base.servo_period * 1e3:.6g} ms")
    else:
        period_note = None
    letter = dict(zip(AXES, base.axis_names))   # q slot -> the machine's letter
    fits: dict[str, AxisIdentification] = {}
    notes: dict[str, str] = {}
    physical: dict[str, PhysicalParameters] = {}
    for axis in AXES:
        if axis not in log.command:
            notes[axis] = f"axis {letter[axis]}: not in the log; kept the base model ({ctrl.name})"
            continue
        if axis not in log.actual:
            notes[axis] = (f"axis {letter[axis]}: the log has its command but not its actual "
                           f"position; kept the base model ({ctrl.name})")
            continue
        X, x = log.command[axis], log.actual[axis]
        try:
            # The base loop's slowest pole sets how long friction transients are left out.
            guard = friction_guard_for(base_models[AXES.index(axis)].poles)
            fits[axis] = identify_axis(letter[axis], X, x, ts, order=order, friction_guard=guard)
        except NotIdentifiable as exc:
            notes[axis] = f"{exc}; kept the base model ({ctrl.name})"
            continue
        if axis in log.current:
            found = identify_physical(base.drives[AXES.index(axis)], x, log.current[axis], ts)
            if found is None:
                notes[axis] = (f"axis {letter[axis]}: too little motion at speed to identify J, B and "
                               "friction from the currents; kept the base drive")
            elif not (np.isfinite(found.J) and found.J > 0 and np.isfinite(found.B)):
                # a machine file needs J > 0: say which log and column, not the file's key
                raise InputError(f"the motor current of {letter[axis]} does not fit its motion: it "
                                 f"gives an inertia J = {found.J:.4g} kg m^2 (must be > 0); is "
                                 "its sign or scale (A, kt) that of the drive's torque?",
                                 source=log.source, field=f"I_{letter[axis]}")
            else:
                physical[axis] = found
    if not fits:
        raise InputError("no axis of the log can be identified: " + "; ".join(
            notes[a] for a in AXES if a in notes), source=log.source)
    if period_note:
        notes["period"] = period_note

    data = copy.deepcopy(base_data)
    table = {"type": "tf"}
    # The controller the drives run, for learning against the virtual machine with friction
    # (a tf loop has none), named only when every identified axis got its J, B and friction
    # from currents: learning against the base drives, whose J and B the log just showed to
    # be off, makes compensation worse than the identified loops alone (docs/identification-measured.md).
    drives_controller = ctrl.base if is_closed_loop(ctrl) else ctrl.name
    if drives_controller is not None and drives_controller != name and set(physical) >= set(fits):
        table["base"] = drives_controller
    elif drives_controller is not None:
        notes["base"] = (f"no base controller named for learning: J, B and friction were not "
                         f"identified for axes {', '.join(letter[a] for a in fits if a not in physical)} "
                         "(no motor currents); compensate --learn runs the identified loops")
    for i, axis in enumerate(AXES):
        if axis in fits:
            num, den = fits[axis].num, fits[axis].den
        else:
            den = base_models[i].den / base_models[i].den[0]
            num = np.polysub(base_models[i].den, base_models[i].num) / base_models[i].den[0]
            num = np.trim_zeros(num, "f")
        table[letter[axis]] = {"num": [float(v) for v in num], "den": [float(v) for v in den]}
    controllers = data.setdefault("controllers", {})
    if name in controllers:
        notes["name"] = f"controller {name!r} of the base machine replaced"
    controllers[name] = table
    for axis, p in physical.items():
        drive = data["drives"][letter[axis]]
        drive["J"], drive["B"] = p.J, p.B
        if p.friction is not None:
            drive["friction"] = {k: float(getattr(p.friction, k)) for k in (
                "Ts_pos", "W1_pos", "Tc_pos", "W2_pos", "Ts_neg", "W1_neg", "Tc_neg", "W2_neg")}
    header = (f"Machine {base.name} with controller {name!r} identified from the servo log "
              f"{log.source}\n({log.n_samples} samples at {ts * 1e3:.6g} ms) by precontour "
              "identify: x/X per axis, continuous time, highest power first.")
    if physical:
        header += f"\nDrives {', '.join(letter[a] for a in physical)}: J, B and friction identified from motor currents."
    text = machine_file_text(data, header)
    machine = parse_machine(text, source="<identified machine>")
    return IdentificationResult(log=log, base=base, base_controller=ctrl, name=name, axes=fits,
                                notes=notes, physical=physical, machine=machine, text=text,
                                base_models=base_models)
