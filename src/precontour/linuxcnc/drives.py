"""Simulated drives for a LinuxCNC configuration: each joint closed through LinuxCNC's own
``pid`` component around a drive plant built from stock HAL components.

What ``precontour linuxcnc-config --drives simulated`` adds to the configuration of
:mod:`precontour.linuxcnc.config`: instead of looping each joint's command back as its
feedback, the joint's ``motor-pos-cmd`` goes to ``pid.<axis>`` (P, I, D and the velocity and
acceleration feed-forwards FF1, FF2), whose output, in volts, drives the plant of spec section
2 at the motor:

    J w' = ka kt u - B w - Tf(w),     x' = rg w

with the machine file's drive parameters (``ka``, ``kt``, ``rg``, ``J``, ``B``) and the Coulomb
part of its friction (``Tc_pos`` / ``Tc_neg``: the torque that opposes motion of each sign).
The plant is made of ``sum2``, ``scale``, ``limit1`` and ``integ`` components, one chain per
joint, computed once per servo period after the motion controller and the ``pid``:

- the net torque ``ka kt u - B w`` (``sum2``),
- the friction ``Tf = clip(G w, Tc_neg, Tc_pos)`` with ``G = J / Ts`` (``scale`` then
  ``limit1``): a resting motor stays at rest while the drive torque is within the friction
  band, as under Coulomb friction, since a friction torque of ``J w / Ts`` cancels in one
  period whatever speed is left (a speed-proportional band narrower than that would ring, one
  wider would creep),
- ``w' = (net - Tf) / J`` (``sum2``), integrated to the speed (``integ``), scaled by ``rg`` (and
  180/pi on rotary joints, which LinuxCNC has in degrees) and integrated again to the position
  that goes back to the ``pid`` and to the joint's ``motor-pos-fb`` (semi-implicit Euler: the
  position integrates the new speed).

LinuxCNC's ``pid`` works in the joint's units (mm, degrees): gains per rad are scaled by
pi/180 on rotary joints. The feed-forwards are the machine file's model feed-forwards
(``kvff``, ``kaff`` as fractions of the nominal damping and inertia torques): FF1 = kvff B / K,
FF2 = kaff J / K with K = ka kt rg. Only ``pid`` controllers run here (LinuxCNC has no other
position loop component); a closed loop given as a transfer function (``tf``) runs its
``base`` controller.

The recorder then samples the actual positions (``motor-pos-fb``) beside the commands, so that
a recording is a servo log (:func:`recording_servo_log`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import InputError

#: Columns the recorder samples besides the looped-back configuration's: each joint's actual
#: position (``joint.N.motor-pos-fb``, the plant's output), mm or degrees.
ACTUAL_COLUMNS: tuple[str, ...] = ("a0", "a1", "a2", "a3", "a4")

#: What ``--drives`` takes: the joints looped back (LinuxCNC's sims), or closed through
#: ``pid`` around a simulated plant.
DRIVES = ("looped", "simulated")

#: Following-error limits written for simulated drives (mm, or degrees on rotary joints): at
#: speed (FERROR) and at rest (MIN_FERROR). LinuxCNC's checks stay on; these are far above
#: the micrometre errors the bench measures, and trip on a loop that runs away.
FERROR = 1.0
MIN_FERROR = 0.5


@dataclass(frozen=True)
class JointPlant:
    """One joint's ``pid`` gains (joint units) and plant constants."""

    letter: str
    p: float
    i: float
    d: float
    ff1: float
    ff2: float
    torque_gain: float      # ka kt, N m / V
    damping: float          # B, kg m^2 / s
    inertia: float          # J, kg m^2
    friction_gain: float    # G = J / Ts, N m s / rad
    friction_pos: float     # Tc_pos >= 0, N m
    friction_neg: float     # Tc_neg <= 0, N m
    rate: float             # joint units per motor rad (rg, times 180/pi on rotary joints)


def joint_plants(machine, controller: str) -> tuple[JointPlant, ...]:
    """The five joints' ``pid`` gains and plants for ``controller`` of ``machine``."""
    ctrl = machine.controller(controller)
    source = machine.source or machine.name
    if ctrl.type == "tf":
        if not ctrl.base:
            raise InputError(f"controller {controller!r} is a closed loop (tf) with no base "
                             "controller: simulated drives need the drives' own controller "
                             "(a pid)", source=source, field=f"controllers.{controller}")
        ctrl = machine.controller(ctrl.base)
    if ctrl.type != "pid":
        raise InputError(f"controller {ctrl.name!r} is of type {ctrl.type!r}; LinuxCNC's "
                         "position loop is its pid component: simulated drives need a pid "
                         "controller", source=source, field=f"controllers.{ctrl.name}")
    plants = []
    for letter, drive, gains in zip(machine.axis_names, machine.drives, ctrl.axes):
        # per rad -> per degree on rotary joints (LinuxCNC's unit)
        unit = math.pi / 180.0 if drive.is_rotary else 1.0
        K = drive.gain
        tc_pos = tc_neg = 0.0
        if drive.friction is not None:
            tc_pos = max(float(drive.friction.Tc_pos), 0.0)
            tc_neg = min(float(drive.friction.Tc_neg), 0.0)
        plants.append(JointPlant(
            letter=letter, p=gains.kp * unit, i=gains.ki * unit, d=gains.kd * unit,
            ff1=gains.kvff * drive.B / K * unit, ff2=gains.kaff * drive.J / K * unit,
            torque_gain=drive.ka * drive.kt, damping=drive.B, inertia=drive.J,
            friction_gain=drive.J / machine.servo_period, friction_pos=tc_pos,
            friction_neg=tc_neg, rate=drive.rg / unit))
    return tuple(plants)


def _num(value: float) -> str:
    return f"{value:.12g}"


#: Columns the recorder samples for the overlay: each joint's overlay offset (``o0``..``o4``,
#: mm or degrees), added by ``offset`` components between the motion controller and the pid.
OVERLAY_COLUMNS: tuple[str, ...] = ("o0", "o1", "o2", "o3", "o4")
#: The motion controller's digital output that starts the overlay: the program turns it on
#: with ``M62 P0`` before its first move (synchronised with the start of that move).
OVERLAY_OUTPUT = 0
#: Seconds of overlay samples the overlay streamer's FIFO holds.
OVERLAY_BUFFER_SECONDS = 2.0


def drives_hal(plants: tuple[JointPlant, ...], extra_sum2: tuple[str, ...] = (),
               period_ns: int = 1_000_000) -> list[str]:
    """HAL lines that load, wire and schedule the ``pid`` and plant of every joint (after
    ``motion-controller`` in the servo thread). ``extra_sum2``: names of ``sum2`` instances
    the rest of the configuration needs (a component loads once, with all its names)."""
    names = [p.letter.lower() for p in plants]
    sum2 = list(extra_sum2) + [f"drive-{n}-{part}" for n in names for part in ("net", "accel")]
    depth = int(math.ceil(OVERLAY_BUFFER_SECONDS * 1e9 / period_ns))
    lines = ["# simulated drives (linuxcnc-config --drives simulated): pid.N closes each joint",
             "# around J w' = ka kt u - B w - Tf(w), x' = rg w (stock components; see",
             "# precontour.linuxcnc.drives)",
             "# the overlay: a servo-rate correction per joint (run --overlay's file, fed by",
             "# halstreamer) added between motion and the pid by offset components (motion",
             "# sees the feedback less it: its following-error check stays on); "
             f"M62 P{OVERLAY_OUTPUT} in the",
             "# program starts it, synchronised with the next move",
             # LinuxCNC 2.9's streamer takes no names=: instance 0 (stream.hal's own runs in a
             # halrun session of its own)
             f"loadrt streamer depth={depth} cfg={'f' * len(plants)}",
             "loadrt offset names=" + ",".join(f"overlay-{n}" for n in names),
             "addf streamer.0 servo-thread",
             f"net overlay-enable motion.digital-out-{OVERLAY_OUTPUT:02d} => streamer.0.enable",
             f"loadrt pid names={','.join(f'pid.{n}' for n in names)}",
             f"loadrt sum2 names={','.join(sum2)}",
             "loadrt scale names=" + ",".join(f"drive-{n}-{part}" for n in names
                                               for part in ("fgain", "rate")),
             "loadrt limit1 names=" + ",".join(f"drive-{n}-friction" for n in names),
             "loadrt integ names=" + ",".join(f"drive-{n}-{part}" for n in names
                                              for part in ("speed", "pos"))]
    for joint, p in enumerate(plants):
        n = p.letter.lower()
        d = f"drive-{n}"
        lines += [
            f"# joint {joint} ({p.letter})",
            f"addf overlay-{n}.update-output servo-thread",
            f"addf pid.{n}.do-pid-calcs servo-thread",
            *[f"addf {d}-{part} servo-thread"
              for part in ("net", "fgain", "friction", "accel", "speed", "rate", "pos")],
            f"setp pid.{n}.Pgain {_num(p.p)}", f"setp pid.{n}.Igain {_num(p.i)}",
            f"setp pid.{n}.Dgain {_num(p.d)}", f"setp pid.{n}.FF1 {_num(p.ff1)}",
            f"setp pid.{n}.FF2 {_num(p.ff2)}", f"setp pid.{n}.maxoutput 0",
            f"setp {d}-net.gain0 {_num(p.torque_gain)}",
            f"setp {d}-net.gain1 {_num(-p.damping)}",
            f"setp {d}-fgain.gain {_num(p.friction_gain)}",
            f"setp {d}-friction.min {_num(p.friction_neg)}",
            f"setp {d}-friction.max {_num(p.friction_pos)}",
            f"setp {d}-accel.gain0 {_num(1.0 / p.inertia)}",
            f"setp {d}-accel.gain1 {_num(-1.0 / p.inertia)}",
            f"setp {d}-rate.gain {_num(p.rate)}",
            f"net j{joint}-cmd joint.{joint}.motor-pos-cmd => overlay-{n}.in",
            f"net j{joint}-overlay streamer.0.pin.{joint} => overlay-{n}.offset",
            f"net j{joint}-overlaid overlay-{n}.out => pid.{n}.command",
            f"net j{joint}-enable joint.{joint}.amp-enable-out => pid.{n}.enable",
            f"net j{joint}-volts pid.{n}.output => {d}-net.in0",
            f"net j{joint}-speed {d}-speed.out => {d}-net.in1 {d}-fgain.in {d}-rate.in",
            f"net j{joint}-fgain {d}-fgain.out => {d}-friction.in",
            f"net j{joint}-friction {d}-friction.out => {d}-accel.in1",
            f"net j{joint}-net {d}-net.out => {d}-accel.in0",
            f"net j{joint}-accel {d}-accel.out => {d}-speed.in",
            f"net j{joint}-rate {d}-rate.out => {d}-pos.in",
            f"net j{joint}-pos {d}-pos.out => pid.{n}.feedback overlay-{n}.fb-in",
            f"net j{joint}-fb overlay-{n}.fb-out => joint.{joint}.motor-pos-fb",
        ]
    lines += [f"addf overlay-{n}.update-feedback servo-thread" for n in names]
    return lines
