import numpy as np
import pytest

from precontour.errors import InputError
from precontour.trajectory.sampled import MIN_SAMPLES, check_uniform_time


def test_step_change_is_reported_at_the_first_row_with_the_new_step():
    t = np.concatenate([np.arange(1000) * 1e-3, 0.999 + 2e-3 * np.arange(1, 501)])
    # rows 1..1000 are 1 ms apart; row 1001 is 2 ms after row 1000
    with pytest.raises(InputError, match=r"f.csv, row 1001, field 't': time is not uniformly "
                                         r"sampled \(step 0.002 s, the first step is 0.001 s\)"):
        check_uniform_time(t, source="f.csv")


def test_round_off_of_printed_time_stamps_is_uniform():
    t = np.round(1e4 + np.arange(5000) * 1e-3, 9)     # 9 decimals of a large offset
    assert check_uniform_time(t) == pytest.approx(1e-3, rel=1e-9)


def test_one_minimum_number_of_samples():
    assert MIN_SAMPLES == 6
    with pytest.raises(InputError, match="too few samples: 5, need at least 6"):
        check_uniform_time(np.arange(5) * 1e-3, min_samples=MIN_SAMPLES)


def test_messages_show_plain_numbers():
    with pytest.raises(InputError) as info:
        check_uniform_time(np.array([0.0, 1e-3, 1e-3, 3e-3]))
    assert "np." not in str(info.value) and "(0.001 then 0.001)" in str(info.value)
