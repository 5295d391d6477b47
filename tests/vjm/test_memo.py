"""vjm.memo.Recent: each value computed once while kept, the oldest key dropped first, nothing kept from a
computation that raised."""
import pytest

from vjm.memo import Recent


def test_values_are_computed_once_and_the_oldest_goes_first():
    calls = []
    memo = Recent(2)

    def value(k):
        return memo.get(k, lambda: calls.append(k) or k * 10)

    assert [value(1), value(2), value(1), value(3), value(2), value(1)] == [10, 20, 10, 30, 20, 10]
    # 1 and 2 kept; 3 drops 1 (the oldest); 2 is still kept; 1 is computed again and drops 2
    assert calls == [1, 2, 3, 1] and len(memo) == 2


def test_a_computation_that_raises_keeps_nothing():
    memo = Recent(4)

    def bad():
        raise ValueError("no")

    with pytest.raises(ValueError):
        memo.get("k", bad)
    assert len(memo) == 0 and memo.get("k", lambda: 5) == 5
