"""Commands judged on an ensemble, block by block, and the local fallback: by hand and on a toy
machine whose contour error is the command's own offset."""

from __future__ import annotations

import numpy as np
import pytest

from precontour.compensation import blocks
from precontour.compensation.blend import TAPER_HOLD, TAPER_WIDTH
from precontour.prediction.contour import ContourErrors

TS = 1e-3
N = 1000
LINE = np.arange(N) // 100 + 10          # ten source lines of 0.1 s each
STARTS = blocks.block_starts(N, TS, LINE)


def _errors(tip, orientation=None):
    tip = np.asarray(tip, dtype=float)
    orientation = np.zeros_like(tip) if orientation is None else orientation
    return ContourErrors(tip=tip, orientation=orientation, tip_parameter=np.zeros_like(tip),
                         orientation_parameter=np.zeros_like(tip))


def _toy_judge(q, offsets=(0.0,)):
    """One draw per offset: the tip error is |X + offset|, the orientation error |A|."""
    return blocks.judge([_errors(np.abs(q[:, 0] + o), np.abs(q[:, 3])) for o in offsets],
                        STARTS)


def test_block_starts_by_hand():
    np.testing.assert_array_equal(blocks.block_starts(7, TS, np.array([3, 3, 4, 4, 4, 9, 9])),
                                  [0, 2, 5])
    np.testing.assert_array_equal(blocks.block_starts(250, TS), [0, 100, 200])
    np.testing.assert_array_equal(STARTS, np.arange(0, N, 100))
    with pytest.raises(ValueError, match="one entry per sample"):
        blocks.block_starts(5, TS, np.zeros(4))


def test_judgement_against_loops():
    rng = np.random.default_rng(0)
    errors = [_errors(rng.uniform(0, 1e-3, N), rng.uniform(0, 1e-6, N)) for _ in range(3)]
    starts = np.array([0, 10, 400, 401, 999])
    judged = blocks.judge(errors, starts)
    ends = list(starts[1:]) + [N]
    for d, e in enumerate(errors):
        for k, (a, b) in enumerate(zip(starts, ends)):
            assert judged.tip_max[d, k] == e.tip[a:b].max()
            assert judged.tip_mean[d, k] == pytest.approx(e.tip[a:b].mean(), rel=1e-12)
            assert judged.orientation_max[d, k] == e.orientation[a:b].max()
        assert judged.summaries[d] == e.summary()
    worst = judged.worst
    assert worst["tip_max_um"] == max(1e3 * e.tip.max() for e in errors)
    assert judged.score == max(blocks.score(e.summary()) for e in errors)
    assert judged.draws == 3 and judged.finite


def test_margins_by_hand():
    """A block may exceed the reference's worst draw there by 0.1 um or 5 % (tip), 1 urad or
    5 % (orientation), whichever is larger; the comparison is worst draw against worst draw."""
    tip_ref = np.full(N, 1e-3)                  # 1 um: the absolute margin (0.1 um) applies
    tip_ref[500:600] = 10e-3                    # 10 um: 5 % (0.5 um) applies
    reference = blocks.judge([_errors(tip_ref), _errors(0.5 * tip_ref)], STARTS)
    inside = tip_ref.copy()
    inside[0:100] = 1.0999e-3
    inside[500:600] = 10.499e-3
    assert not blocks.worse_blocks(blocks.judge([_errors(inside)] * 2, STARTS),
                                   reference).any()
    over = inside.copy()
    over[0:100] = 1.1001e-3
    over[500:600] = 10.501e-3
    np.testing.assert_array_equal(
        np.flatnonzero(blocks.worse_blocks(blocks.judge([_errors(over)] * 2, STARTS),
                                           reference)), [0, 5])
    # orientation: 1 urad absolute
    ori = blocks.judge([_errors(tip_ref, np.full(N, 10e-6))], STARTS)
    ok = blocks.judge([_errors(tip_ref, np.full(N, 10.99e-6))], STARTS)
    bad = blocks.judge([_errors(tip_ref, np.full(N, 11.01e-6))], STARTS)
    assert not blocks.worse_blocks(ok, ori).any() and blocks.worse_blocks(bad, ori).all()
    # the whole max and mean are compared draw by draw, strictly
    assert blocks.whole_ok(reference, reference)
    swapped = blocks.judge([_errors(0.5 * tip_ref), _errors(tip_ref)], STARTS)
    assert not blocks.whole_ok(swapped, reference)


def test_repeatability_by_hand():
    """The uncompensated command run again: a block's repeatability is the largest change of
    its max over the draws (tip and orientation), and a block is worse only beyond it too."""
    tip = np.full(N, 1e-3)
    first = [_errors(tip), _errors(tip, np.full(N, 2e-6))]
    second_tip = tip.copy()
    second_tip[300:400] = 4e-3                      # block 3: 3 um higher on draw 0
    second_ori = np.full(N, 2e-6)
    second_ori[700:800] = 7e-6                      # block 7: 5 urad higher on draw 1
    reference = blocks.judge(first, STARTS)
    rerun = blocks.judge([_errors(second_tip), _errors(tip, second_ori)], STARTS)
    widened = blocks.with_repeatability(reference, rerun)
    expected_tip = np.zeros(10)
    expected_tip[3] = 3e-3
    expected_ori = np.zeros(10)
    expected_ori[7] = 5e-6
    np.testing.assert_allclose(widened.tip_repeatability, expected_tip, rtol=1e-12, atol=0)
    np.testing.assert_allclose(widened.orientation_repeatability, expected_ori, rtol=1e-12,
                               atol=0)
    # a command 2.5 um worse in block 3 and 4 urad in block 7, and 2.5 um in block 5: worse
    # by the margins alone in all three, beyond the repeatability in block 5 only
    tip_cmd = tip.copy()
    tip_cmd[300:400] = 3.5e-3
    tip_cmd[500:600] = 3.5e-3
    ori_cmd = np.full(N, 2e-6)
    ori_cmd[700:800] = 6e-6
    command = blocks.judge([_errors(tip_cmd), _errors(tip, ori_cmd)], STARTS)
    np.testing.assert_array_equal(np.flatnonzero(blocks.worse_blocks(command, reference)),
                                  [3, 5, 7])
    np.testing.assert_array_equal(np.flatnonzero(blocks.worse_blocks(command, widened)), [5])
    # the rerun itself is not worse than the widened reference anywhere
    assert not blocks.worse_blocks(rerun, widened).any()
    with pytest.raises(ValueError, match="rerun has"):
        blocks.with_repeatability(reference, blocks.judge(first[:1], STARTS))


def test_a_block_that_hurts_falls_back_and_nothing_else_moves():
    q_ref = np.zeros((N, 5))
    q_ref[:, 0] = 1e-3                          # uncompensated: 1 um everywhere
    q = np.zeros((N, 5))                        # compensated: 0 ...
    q[400:500, 0] = 5e-3                        # ... but 5 um in line 14
    gentle = np.full((N, 5), 0.0)
    gentle[:, 0] = 0.5e-3
    fixed, judged, report = blocks.fall_back(q, _toy_judge(q), q_ref, _toy_judge(q_ref),
                                             _toy_judge, STARTS, TS,
                                             fallbacks=[("gentle", gentle)], line=LINE)
    assert report.rounds == 1 and not report.everywhere and len(report.blocks) == 1
    block = report.blocks[0]
    assert (block.line, block.to) == (14, "gentle")
    assert block.start == pytest.approx(0.4) and block.stop == pytest.approx(0.499)
    assert "tip 5 um (draw 0) against 1 um uncompensated" in block.reason
    assert "line 14" in block.format()
    hold = int(TAPER_HOLD / TS)
    reach = hold + int(TAPER_WIDTH / TS) + 2
    # q - 1 (q - target): the target up to round-off
    np.testing.assert_allclose(fixed[400 - hold:500 + hold], gentle[400 - hold:500 + hold],
                               rtol=0, atol=1e-18)
    np.testing.assert_array_equal(fixed[:400 - reach], q[:400 - reach])
    np.testing.assert_array_equal(fixed[500 + reach:], q[500 + reach:])
    assert blocks.nowhere_worse(judged, _toy_judge(q_ref))


def test_fallbacks_that_hurt_too_give_way_to_the_planned_command():
    q_ref = np.zeros((N, 5))
    q_ref[:, 0] = 1e-3
    q = np.zeros((N, 5))
    q[400:500, 0] = 5e-3
    useless = q.copy()
    fixed, _, report = blocks.fall_back(q, _toy_judge(q), q_ref, _toy_judge(q_ref), _toy_judge,
                                        STARTS, TS, fallbacks=[("useless", useless)])
    assert report.rounds == 2 and [b.to for b in report.blocks] == ["planned"]
    np.testing.assert_allclose(fixed[350:550], q_ref[350:550], rtol=0, atol=1e-18)
    # an alternative that is nowhere worse there is tried first
    alternative = np.zeros((N, 5))
    fixed, _, report = blocks.fall_back(
        q, _toy_judge(q), q_ref, _toy_judge(q_ref), _toy_judge, STARTS, TS,
        alternatives=[("fine", alternative, _toy_judge(alternative))],
        fallbacks=[("useless", useless)])
    assert report.rounds == 1 and [b.to for b in report.blocks] == ["fine"]
    np.testing.assert_allclose(fixed, alternative, rtol=0, atol=1e-18)
    # a blend the admissibility check refuses moves on before it is judged
    calls = []

    def judge_counting(q_try):
        calls.append(1)
        return _toy_judge(q_try)

    fixed, _, report = blocks.fall_back(
        q, _toy_judge(q), q_ref, _toy_judge(q_ref), judge_counting, STARTS, TS,
        fallbacks=[("gentle", np.zeros((N, 5)))],
        admissible=lambda q_try: not np.array_equal(q_try[450], np.zeros(5)))
    assert [b.to for b in report.blocks] == ["planned"] and len(calls) == 1


def test_when_nothing_helps_the_planned_command_is_taken_everywhere():
    q_ref = np.zeros((N, 5))
    q_ref[:, 0] = 1e-3
    q = np.zeros((N, 5))
    q[400:500, 0] = 5e-3

    def hostile(q_try):     # anything but the planned command hurts in line 14
        if np.array_equal(q_try, q_ref):
            return _toy_judge(q_ref)
        return _toy_judge(np.where(np.arange(N)[:, None] // 100 == 4, 5e-3, np.zeros((N, 5))))

    fixed, judged, report = blocks.fall_back(q, hostile(q), q_ref, hostile(q_ref), hostile,
                                             STARTS, TS)
    assert report.everywhere and fixed is q_ref
    assert report.rounds == 3           # the planned command held 50, 100 and 200 ms
    assert report.format() == "fell back to the planned command everywhere"
    # and a command that does not hurt is left alone, without a judgement
    same, _, none = blocks.fall_back(q_ref, _toy_judge(q_ref), q_ref, _toy_judge(q_ref),
                                     None, STARTS, TS)
    assert same is q_ref and none.rounds == 0 and not none.blocks


def test_a_round_that_hurts_in_more_blocks_ends_the_fallback():
    """Where a round's blends leave more blocks hurting than before it (here its neighbours:
    every blend into line 14 makes lines 13-15 5 um worse), the fallback gives up at once:
    the planned command everywhere after one judgement, not after every option (issue 21's
    LinuxCNC impeller: 13 s of fallbacks that grew and failed)."""
    q_ref = np.zeros((N, 5))
    q_ref[:, 0] = 1e-3
    q = np.zeros((N, 5))
    q[400:500, 0] = 5e-3
    calls = []

    def spreading(q_try):
        calls.append(1)
        if np.array_equal(q_try, q_ref) or q_try is q:
            return _toy_judge(q_try)
        line = np.arange(N)[:, None] // 100
        return _toy_judge(np.where((line >= 3) & (line <= 5), 5e-3, np.zeros((N, 5))))

    judged, reference = spreading(q), spreading(q_ref)
    calls.clear()
    fixed, judged, report = blocks.fall_back(q, judged, q_ref, reference, spreading, STARTS,
                                             TS)
    assert report.everywhere and fixed is q_ref and report.rounds == 1 and len(calls) == 1


def test_a_non_finite_judgement_is_nowhere_admissible():
    reference = _toy_judge(np.zeros((N, 5)))
    bad = blocks.not_finite(1, STARTS.size)
    assert not bad.finite and bad.score == float("inf")
    assert not blocks.whole_ok(bad, reference) and blocks.worse_blocks(bad, reference).all()
