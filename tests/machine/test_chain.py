"""The generic chain (machine-file type ``chain``) against every other type as its preset
(:func:`precontour.machine.kinematics.chain_of`): the same tip, orientation, linear axes,
Jacobian and path inverse; against the independent 4 x 4 chain of tests/machine/
test_families.py; and the machine file's ``chain`` tables, read and refused."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from precontour.errors import MachineFileError
from precontour.machine import parse_machine
from precontour.machine.kinematics import ChainKinematics, RotaryAxis, chain_of
from precontour.machine.kinematics.ac_trunnion import POLE_TOLERANCE
from precontour.machine.machine_file import builtin_machine_text

from test_families import FAMILIES, chain_of as oracle_of
from test_kinematics import ALL_KINEMATICS

finite = dict(allow_nan=False, allow_infinity=False)
poses = st.tuples(st.floats(-300, 300, **finite), st.floats(-300, 300, **finite),
                  st.floats(-300, 300, **finite), st.floats(-3.0, 3.0, **finite),
                  st.floats(-20, 20, **finite))
PRESETS = pytest.mark.parametrize("kin", list(ALL_KINEMATICS.values()), ids=list(ALL_KINEMATICS))


@PRESETS
@settings(max_examples=100, deadline=None)
@given(q=poses)
def test_preset_chain_equals_the_type(kin, q):
    chain = chain_of(kin)
    q = np.array(q)
    P, O = kin.forward(q)
    P_chain, O_chain = chain.forward(q)
    np.testing.assert_allclose(P_chain, P, rtol=0, atol=1e-9)
    np.testing.assert_allclose(O_chain, O, rtol=0, atol=1e-14)
    np.testing.assert_allclose(chain.orientation(q), O, rtol=0, atol=1e-14)
    np.testing.assert_allclose(chain.linear_axes(P, q[3], q[4]), q[:3], rtol=0, atol=1e-9)
    assert chain.axis_names == kin.axis_names
    assert chain.tilt_limits == kin.tilt_limits


@PRESETS
def test_preset_chain_has_the_types_jacobian_and_path_inverse(kin):
    chain = chain_of(kin)
    rng = np.random.default_rng(3)
    A, C = rng.uniform(-3, 3, 50), rng.uniform(-7, 7, 50)
    np.testing.assert_allclose(chain.orientation_jacobian(A, C), kin.orientation_jacobian(A, C),
                               rtol=0, atol=1e-14)
    # a path: a cone of tool axes around a tilted axis, swinging through the pole and back
    s = np.linspace(0, 1, 3000)
    tilt = 0.9 * np.sin(3 * np.pi * s)
    turn = 4 * np.pi * s
    O = np.stack([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)], 1)
    P = np.stack([60 * np.cos(turn), 40 * np.sin(turn), 10 * s], axis=1)
    q_kin, q_chain = kin.inverse(P, O), chain.inverse(P, O)
    np.testing.assert_allclose(q_chain, q_kin, rtol=0, atol=1e-9)
    P2, O2 = chain.forward(q_chain)
    np.testing.assert_allclose(P2, P, atol=1e-9)
    np.testing.assert_allclose(O2, O, atol=2 * POLE_TOLERANCE + 1e-15)


@pytest.mark.parametrize("kin", list(FAMILIES.values()), ids=list(FAMILIES))
@settings(max_examples=60, deadline=None)
@given(q=poses)
def test_chain_equals_the_independent_chain(kin, q):
    P, O = chain_of(kin).forward(np.array(q))
    P_ref, O_ref = oracle_of(kin).forward(q)
    np.testing.assert_allclose(P, P_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(O, O_ref, rtol=0, atol=1e-14)


HEAD_TABLE_AC = """
[kinematics]
type = "chain"
tool_offset = 40.0
[kinematics.A]
carried_by = "head"
direction = [1, 0, 0]
point = [0, 0, 120]
[kinematics.C]
carried_by = "table"
direction = [0, 0, -1]
point = [15, -5, 0]
"""


def _machine_text(kinematics: str) -> str:
    # the drives and controllers of the built-in machine of this family (A-C axis names)
    text = builtin_machine_text("zhang2013")
    body = text[text.index("[drives.X]"):]
    return "name = \"t\"\n" + kinematics + "\n" + body


def test_chain_machine_file_reads_a_head_table_ac_machine():
    machine = parse_machine(_machine_text(HEAD_TABLE_AC))
    kin = machine.kinematics
    assert isinstance(kin, ChainKinematics) and machine.axis_names == ("X", "Y", "Z", "A", "C")
    assert kin.tilt == RotaryAxis("A", "head", (1.0, 0.0, 0.0), (0.0, 0.0, 120.0))
    # A head tilting about +x, C table turning left-handed about +z: O = Rz(C) Rx(A) ez
    q = np.array([3.0, -4.0, 5.0, 0.4, 1.1])
    P, O = kin.forward(q)
    a, c = 0.4, 1.1
    np.testing.assert_allclose(O, [np.sin(a) * np.sin(c), -np.sin(a) * np.cos(c), np.cos(a)],
                               atol=1e-15)
    np.testing.assert_allclose(kin.inverse(P, O, c_near=np.array(c)), q, atol=1e-9)


@pytest.mark.parametrize("change, message", [
    (("direction = [1, 0, 0]", "direction = [1, 1, 0]"),
     r"\[kinematics.A\] direction: must be \+-x"),
    (('carried_by = "head"', 'carried_by = "ram"'), "carried_by: unknown value"),
    ((None, None), "does not orient the tool"),
    (("tool_offset = 40.0", "tool_offset = 40.0\nlinear_senses = [1, 2, 1]"),
     "linear_senses: must be"),
    (("point = [0, 0, 120]", "point = [0, 120]"), "point: must be a list of at least 3"),
    (("[kinematics.A]", "[kinematics.B]"), r"\[kinematics.B\] direction: must be \+-y"),
    (("direction = [1, 0, 0]", "direction = [1, 0, 0]\n[kinematics.B]\ncarried_by = \"head\""),
     "one tilt axis"),
    (("point = [0, 0, 120]", "point = [0, 0, 120]\nsense = 1"), "sense: unknown key"),
])
def test_chain_machine_file_errors_name_the_key(change, message):
    if change == (None, None):   # the sides swapped: an A table under a C head
        text = (HEAD_TABLE_AC.replace('"head"', '"@"').replace('"table"', '"head"')
                .replace('"@"', '"table"'))
    else:
        text = HEAD_TABLE_AC.replace(*change)
    assert text != HEAD_TABLE_AC
    with pytest.raises(MachineFileError, match=message):
        parse_machine(_machine_text(text), source="m.toml")


def _oracle_of_chain(kin: ChainKinematics):
    """The independent 4 x 4 chain of a ChainKinematics, from its description: head axes from
    the ram outwards (C carries the tilt), table axes from the base outwards (the tilt carries
    C), each turning right-handed about its direction."""
    from test_families import Axis, Chain

    def axis(a, slot):
        return Axis(slot, np.array(a.direction), np.array(a.point), 1.0)

    pairs = ((kin.turn, 4), (kin.tilt, 3))
    head = tuple(axis(a, s) for a, s in pairs if a.side == "head")
    table = tuple(axis(a, s) for a, s in reversed(pairs) if a.side == "table")
    return Chain(head=head, table=table, tool=kin.tool_offset, linear=kin.linear_senses,
                 frame=(np.eye(3), -np.array(kin.workpiece_origin)))


sign = st.sampled_from([1.0, -1.0])
coordinate = st.floats(-200, 200, **finite)
chains = st.builds(
    lambda tilt_letter, sides, s_tilt, s_turn, p_tilt, p_turn, tool, senses, origin:
    ChainKinematics(
        tilt=RotaryAxis(tilt_letter, sides[0],
                        tuple(s_tilt * np.eye(3)[0 if tilt_letter == "A" else 1]), p_tilt),
        turn=RotaryAxis("C", sides[1], (0.0, 0.0, s_turn), p_turn),
        tool_offset=tool, linear_senses=senses, workpiece_origin=origin),
    st.sampled_from(["A", "B"]),
    st.sampled_from([("table", "table"), ("head", "table"), ("head", "head")]),
    sign, sign, st.tuples(coordinate, coordinate, coordinate),
    st.tuples(coordinate, coordinate, coordinate), st.floats(0, 300, **finite),
    st.tuples(sign, sign, sign), st.tuples(coordinate, coordinate, coordinate))


@settings(max_examples=300, deadline=None)
@given(kin=chains, q=poses)
def test_any_chain_equals_the_independent_chain_and_inverts(kin, q):
    q = np.array(q)
    P, O = kin.forward(q)
    P_ref, O_ref = _oracle_of_chain(kin).forward(q)
    np.testing.assert_allclose(P, P_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(O, O_ref, rtol=0, atol=1e-14)
    np.testing.assert_allclose(kin.orientation(q), O, rtol=0, atol=1e-14)
    # round trip through the inverse, on the branch of q
    if abs(np.sin(q[3])) > 1e-6:
        np.testing.assert_allclose(kin.inverse(P, O, c_near=np.array(q[4])), q, atol=1e-9)
    # the tool axis: one mm less of tool moves the tip by O
    from dataclasses import replace
    P_short, _ = replace(kin, tool_offset=kin.tool_offset - 1.0).forward(q)
    np.testing.assert_allclose(P_short - P, O, rtol=0, atol=1e-11)
