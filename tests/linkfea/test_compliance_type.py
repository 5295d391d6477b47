"""Compliance.congruence: D C D without a second check is the checked matrix, bit for bit."""
import numpy as np
import pytest

from linkfea.mechanics.compliance import Compliance
from linkfea.runtime.errors import LinkFeaError


def test_a_congruence_is_the_checked_product_bit_for_bit():
    rng = np.random.default_rng(4)
    A = rng.standard_normal((6, 6))
    c = Compliance(A @ A.T + 6 * np.eye(6))
    for _ in range(20):
        d = np.exp(rng.uniform(-1.0, 1.0, 6))
        fast = c.congruence(d)
        checked = Compliance(c.matrix * np.outer(d, d))
        assert np.array_equal(fast.matrix, checked.matrix) and fast.frame is None
        assert not fast.matrix.flags.writeable
        # the check would pass: symmetric and positive definite
        assert np.array_equal(fast.matrix, fast.matrix.T) and np.linalg.eigvalsh(fast.matrix)[0] > 0
    for bad in ([1, 1, 1, 1, 1, 0], [1, 1, 1, 1, 1, -2], [1, 1, 1, 1, 1, np.nan], [1, 2]):
        with pytest.raises(LinkFeaError):
            c.congruence(bad)
