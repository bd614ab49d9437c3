"""The exact-strain prototype of the second-order step (issue 34, docs/light_damping.md): for
small slopes it is the second-order (von Karman) shortening, and its derivatives are those of its
strain (finite differences)."""
import numpy as np
import pytest

from tmm_core.second_order import Segments, exact_strain, shape_products

L = 0.04
SEG = Segments(np.array([0]), np.array([3]), np.array([L]), np.array([5.7e6]), np.array([2e-5]))


def _state(scale, seed=1):
    rng = np.random.default_rng(seed)
    z = rng.normal(size=6) * scale
    z[3] = z[0]                         # no axial stretch: the excess is the shortening alone
    return z, rng.normal(size=6) * scale * 100


def test_small_slopes_give_the_second_order_shortening():
    z, v = _state(1e-5)
    excess = exact_strain(SEG, z, v)[0]
    assert excess * L == pytest.approx(shape_products(SEG, z)[0], rel=1e-6)


@pytest.mark.parametrize("scale", [1e-4, 1e-2])
def test_the_derivatives_are_those_of_the_strain(scale):
    z, v = _state(scale)
    z[3] += 0.3 * scale
    excess, rate, c_a, g = exact_strain(SEG, z, v)

    def strain(zz):
        return exact_strain(SEG, zz, v)[0][0] + (zz[3] - zz[0]) / L

    h = 1e-7 * scale
    assert rate[0] == pytest.approx((exact_strain(SEG, z + h * v / (100 * scale), v)[0][0] - excess[0]) /
                                    (h / (100 * scale)), rel=1e-4)
    for j, i in enumerate((1, 2, 4, 5)):
        dz = np.zeros(6)
        dz[i] = h
        assert g[0, j] == pytest.approx(L * (strain(z + dz) - strain(z - dz)) / (2 * h), rel=1e-3, abs=1e-12)
    dz = np.zeros(6)
    dz[3] = h
    assert c_a[0] == pytest.approx(L * (strain(z + dz) - strain(z - dz)) / (2 * h), rel=1e-4)
