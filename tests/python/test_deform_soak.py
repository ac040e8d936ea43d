"""Random small rigs against the brute-force scatter (random_rigs.py). The seeds below each broke exactness once
(a closed cube whose far corners lay in a block that was not kept: the closure test relied on labels a query cannot
read, and a small ball poking out of a big one between lattice points went missing); scripts/soak_deform.py runs
thousands."""
import pytest

from random_rigs import mismatch


@pytest.mark.parametrize("seed", [90, 233, 464, 1159, 2339, 3145, 5164, 5818])
def test_random_rigs_equal_the_brute_force_scatter(seed):
    assert mismatch(seed) is None
