"""coevo.exactmath: accurate, and the same bits from its array forms (numpy) and its scalar forms (numba)."""

from __future__ import annotations

import math
from decimal import Decimal, getcontext

import numpy as np
import pytest

from coevo import exactmath as em

_PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899862803")


def _values(n: int = 200_000) -> np.ndarray:
    rng = np.random.default_rng(0)
    special = [0.0, -0.0, 1e-300, -1e-300, 5e-324, math.pi, -math.pi, math.pi / 2, -math.pi / 2, 2 * math.pi,
               math.pi / 4, 3 * math.pi / 4, 1e5, -1e5, 1e6]
    k = np.arange(-40, 41) * (math.pi / 4)  # the edges of the reduction's quadrants, and next to them
    return np.concatenate([special, k, np.nextafter(k, np.inf), np.nextafter(k, -np.inf), rng.uniform(-7.0, 7.0, n),
                           rng.uniform(-1e-4, 1e-4, n // 10), rng.uniform(-500, 500, n // 10)])


def _ulps(ours: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(ours - ref) / np.spacing(np.maximum(np.abs(ref), 1e-300))))


def test_constants_are_the_values_they_claim() -> None:
    getcontext().prec = 70
    pio2 = _PI / 2
    assert Decimal(em._PIO2_1) + Decimal(em._PIO2_2) + Decimal(em._PIO2_3) - pio2 < Decimal("1e-36")
    for part in (em._PIO2_1, em._PIO2_2):  # 33 significant bits: k * part is exact for |k| < 2**20
        assert math.frexp(part)[0] * 2**33 == int(math.frexp(part)[0] * 2**33)
    assert em._PIO2 == float(pio2) and em._PI == float(_PI) and em._TWO_OVER_PI == float(2 / _PI)
    for k in range(5):
        assert em._ANGLE[k] == float(k * _PI / 16)
        assert em._CENTRE[k] == pytest.approx(math.tan(k * math.pi / 16), rel=1e-15, abs=0)
    for k in range(4):
        assert em._EDGE[k] == pytest.approx(math.tan((2 * k + 1) * math.pi / 32), rel=1e-15)


def test_sine_and_cosine_within_one_ulp_of_libm() -> None:
    x = _values()
    s, c = em.sincos(x)
    assert _ulps(s, np.sin(x)) <= 1.0 and _ulps(c, np.cos(x)) <= 1.0
    assert em.sin(x).tobytes() == s.tobytes() and em.cos(x).tobytes() == c.tobytes()


def test_arctangent_within_three_ulps_of_libm() -> None:
    rng = np.random.default_rng(1)
    y, x = rng.uniform(-400, 400, (2, 200_000))
    y[:50], x[50:100], x[100:150] = 0.0, 0.0, -3.0  # the axes
    ref = np.array([math.atan2(a, b) for a, b in zip(y.tolist(), x.tolist())])
    assert _ulps(em.atan2(y, x), ref) <= 3.0
    assert em.atan2(0.0, 0.0) == 0.0 and em.atan2(0.0, -1.0) == math.pi and em.atan2(-1.0, 0.0) == -math.pi / 2


def test_non_finite_give_nan() -> None:
    s, c = em.sincos(np.array([np.nan, np.inf, -np.inf]))
    assert np.isnan(s).all() and np.isnan(c).all()
    with np.errstate(invalid="ignore"):
        assert all(math.isnan(v) for v in em.sincos_scalar(float("inf")) + em.sincos_scalar(float("nan")))


def test_scalar_forms_give_the_same_bits_in_python() -> None:
    x = _values(20_000)
    s, c = em.sincos(x)
    got = np.array([em.sincos_scalar(v) for v in x.tolist()])
    assert got[:, 0].tobytes() == s.tobytes() and got[:, 1].tobytes() == c.tobytes()
    y = np.roll(x, 7) * 37.0
    a = em.atan2(y, x)
    assert np.array([em.atan2_scalar(u, v) for u, v in zip(y.tolist(), x.tolist())]).tobytes() == a.tobytes()


def test_scalar_forms_give_the_same_bits_compiled() -> None:
    """As numba compiles them for the world's kernels (coevo.tasks.fuel.kernels)."""
    numba = pytest.importorskip("numba")
    sincos = numba.njit(em.sincos_scalar)

    @numba.njit
    def both(x, out):  # pragma: no cover - compiled
        for i in range(x.shape[0]):
            out[i, 0], out[i, 1] = sincos(x[i])

    from coevo.tasks.fuel.kernels import atan2_into

    x = _values()
    out = np.empty((x.size, 2))
    both(x, out)
    s, c = em.sincos(x)
    assert out[:, 0].tobytes() == s.tobytes() and out[:, 1].tobytes() == c.tobytes()
    y = np.roll(x, 11) * -3.0
    ang = np.empty_like(x)
    atan2_into(y, x, ang)
    assert ang.tobytes() == em.atan2(y, x).tobytes()


def test_exponential_and_logarithm_within_two_ulps_of_libm() -> None:
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.uniform(-700, 700, 100_000), rng.uniform(-1, 1, 10_000), [0.0, -0.0, 1.0, -1.0]])
    assert _ulps(em.exp(x), np.array([math.exp(v) for v in x.tolist()])) <= 2.0
    y = np.concatenate([rng.uniform(0, 1e3, 100_000), em.exp(rng.uniform(-700, 700, 10_000)), [0.5, 1.0, 2.0]])
    ref = np.array([math.log(v) for v in y.tolist()])
    nonzero = ref != 0.0
    assert _ulps(em.log(y)[nonzero], ref[nonzero]) <= 2.0 and em.log(np.array([1.0]))[0] == 0.0
    with np.errstate(all="raise"):  # the edges give libm's answers, and no warning
        assert em.exp(np.array([-np.inf, np.inf, 800.0, -800.0])).tolist() == [0.0, np.inf, np.inf, 0.0]
        assert em.log(np.array([0.0, np.inf])).tolist() == [-np.inf, np.inf]
        assert np.isnan(em.log(np.array([-1.0, np.nan]))).all() and np.isnan(em.exp(np.array([np.nan]))).all()
    getcontext().prec = 70
    ln2 = Decimal(2).ln()
    assert abs(Decimal(em._LN2_1) + Decimal(em._LN2_2) - ln2) < Decimal("1e-26")
    assert em._INV_LN2 == float(1 / ln2) and em._SQRT_HALF == float(Decimal("0.5").sqrt())
