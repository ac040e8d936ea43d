"""Random small rigs against the brute-force scatter (random_rigs.py); scripts/soak_deform.py runs thousands. The
first seeds each broke exactness once (a closed cube whose far corners lay in a block that was not kept: the closure
test relied on labels a query cannot read, and a small ball poking out of a big one between lattice points went
missing)."""
import pytest

from random_rigs import collide_mismatch, mismatch


@pytest.mark.parametrize("seed", [90, 233, 464, 1159, 2339, 3145, 5164, 5818])
def test_random_rigs_equal_the_brute_force_scatter(seed):
    assert mismatch(seed) is None


@pytest.mark.parametrize("seed", [6, 7, 14, 17])  # rigid tissue and radius scales; frames in bricks at random
def test_random_rigs_with_rigid_tissue_radius_scales_and_bricks_equal_the_brute_force(seed):
    assert mismatch(seed, extended=True) is None


@pytest.mark.parametrize("seed", [12, 16, 22, 27])  # (tubes in contact: 2177, 407, 667 and 308 voxels)
def test_collide_counts_the_random_tubes_frames_intersected(seed):
    assert collide_mismatch(seed) is None
