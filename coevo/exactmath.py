"""Sine, cosine, arctangent, exponential and logarithm that give the same bits on every machine.

A run's numbers are promised exact: the same seed gives the same curves, and ``coevo replay`` re-plays a run bit
for bit, on any machine (docs/development.md, "What is exact where").  Basic IEEE operations (``+ - * /``,
``sqrt``, ``floor``, ``rint``, comparisons) are correctly rounded everywhere, but the elementary functions are
not: numpy computes ``arctan2`` (and ``exp``, ``log``) with its own SIMD code on a processor with AVX-512 and with
libm's elsewhere, and glibc's ``sin``, ``cos`` and ``atan2`` take other code paths on a processor without FMA;
the last bits differ (measured: 7.7 % of arctan2's values).  A world that senses bearings with them replays
exactly only where it was recorded.

So the world computes them here, from basic operations alone, in a fixed order: a Cody-Waite reduction by pi/2
and Taylor polynomials for sine and cosine; for the arctangent, the ratio of the smaller to the larger coordinate
reduced to within tan(pi/32) of one of five centres tan(k pi/16) and a Taylor polynomial there; for the
exponential a reduction by ln 2 and a Taylor polynomial, for the logarithm the mantissa's atanh series
(Appendix D's landscapes use those two).  Accurate to
about 1 ulp (tests/test_exactmath.py measures it against libm), and the same bits wherever numpy and numba
compile basic arithmetic without contracting ``a*b + c`` into an FMA (neither does).

Each function has an array form for numpy (branch-free, ``np.where``) and a scalar form (``*_scalar``) that
:mod:`coevo.tasks.fuel.kernels` compiles with numba; both perform the same operations in the same order, which
the tests check on millions of values.  The scalar forms import nothing, so this module stays as light as numpy.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["sincos", "sin", "cos", "atan2", "exp", "log", "sincos_scalar", "atan2_scalar"]

# pi/2 split in three (Cody-Waite): the first two parts have 33 significant bits, so k * part is exact for
# |k| < 2**20 (|x| up to ~1.6e6 rad); their sum is pi/2 to ~1e-37.  Derived from pi's decimal digits
# (tests/test_exactmath.py derives them again).
_PIO2_1 = float.fromhex("0x1.921fb54400000p+0")
_PIO2_2 = float.fromhex("0x1.0b4611a600000p-34")
_PIO2_3 = float.fromhex("0x1.3198a2e037073p-69")
_TWO_OVER_PI = float.fromhex("0x1.45f306dc9c883p-1")
# ln 2 split the same way (33 bits, then the rest: their sum is ln 2 to ~1e-27), 1/ln 2, and sqrt(1/2).
_LN2_1 = float.fromhex("0x1.62e42fef00000p-1")
_LN2_2 = float.fromhex("0x1.473de6af278edp-34")
_INV_LN2 = float.fromhex("0x1.71547652b82fep+0")
_SQRT_HALF = float.fromhex("0x1.6a09e667f3bcdp-1")
_PIO2 = float.fromhex("0x1.921fb54442d18p+0")
_PI = float.fromhex("0x1.921fb54442d18p+1")


# sin r = r + r*z*(S0 + z*(S1 + ...)), cos r = 1 + z*(C0 + z*(C1 + ...)), z = r*r, |r| <= pi/4: the first term
# left out is below 1e-19 of the result.
_SIN = tuple((-1.0) ** (i + 1) / math.factorial(2 * i + 3) for i in range(8))  # -1/3!, 1/5!, ..., 1/17!
_COS = tuple((-1.0) ** (i + 1) / math.factorial(2 * i + 2) for i in range(9))  # -1/2!, 1/4!, ..., 1/18!
# e^r = 1 + r*(1 + r*(1/2! + r*(...1/14!))), |r| <= ln2/2: the first term left out is below 1e-17 of it.
_EXP = tuple(1.0 / math.factorial(n) for n in range(1, 15))
# ln(1+f) = 2s + 2s*z*(L0 + z*(L1 + ...)), s = f/(2+f), z = s*s, |s| <= 0.1716: 1/3, 1/5, ..., 1/23.
_LOG = tuple(1.0 / (2 * i + 3) for i in range(11))
# atan u = u + u*z*(A0 + z*(A1 + ...)), |u| <= tan(pi/32) ~ 0.0985: the first term left out is below 1e-19 of it.
_ATAN = tuple((-1.0) ** (i + 1) / (2 * i + 3) for i in range(8))  # -1/3, 1/5, ..., 1/17
# The arctangent's centres tan(k pi/16), k = 0..4, their angles k pi/16, and the midpoints tan((2k-1) pi/32),
# each the double nearest to its value (computed with 60 decimal digits; tests/test_exactmath.py checks them).
_CENTRE = (0.0, 0.198912367379658, 0.41421356237309503, 0.6681786379192989, 1.0)
_ANGLE = (0.0, 0.19634954084936207, 0.39269908169872414, 0.5890486225480862, 0.7853981633974483)
_EDGE = (0.09849140335716425, 0.3033466836073424, 0.5345111359507917, 0.8206787908286604)
_CENTRE_A, _ANGLE_A, _EDGE_A = np.array(_CENTRE), np.array(_ANGLE), np.array(_EDGE)
_TINIEST = 5e-324  # the smallest positive double: a denominator that is never 0


def _horner(z: np.ndarray | float, coefs: tuple[float, ...]) -> np.ndarray | float:
    p: np.ndarray | float = coefs[-1]
    for c in coefs[-2::-1]:
        p = c + z * p
    return p


def _reduce(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x = k pi/2 + r, |r| <= pi/4 (a little more for huge x): (r, k's quadrant 0..3)."""
    with np.errstate(invalid="ignore"):  # NaN and inf: r is NaN, their quadrant meaningless
        k = np.rint(x * _TWO_OVER_PI)
        r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
        q = k.astype(np.int64) & 3
    return r, q


def sincos(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sin x, cos x) of an array of radians, float64."""
    x = np.asarray(x, dtype=np.float64)
    r, q = _reduce(x)
    z = r * r
    s = r + r * z * _horner(z, _SIN)
    c = 1.0 + z * _horner(z, _COS)
    odd = (q & 1).astype(bool)  # quadrants 1 and 3: sine and cosine change places ...
    s, c = np.where(odd, c, s), np.where(odd, s, c)
    sin_x = np.where((q & 2).astype(bool), -s, s)  # ... and change signs: sine in quadrants 2, 3, cosine in 1, 2
    cos_x = np.where(((q + 1) & 2).astype(bool), -c, c)
    return sin_x, cos_x


def sin(x: np.ndarray) -> np.ndarray:
    """sin x of an array of radians (:func:`sincos`'s first half)."""
    return sincos(x)[0]


def cos(x: np.ndarray) -> np.ndarray:
    """cos x of an array of radians (:func:`sincos`'s second half)."""
    return sincos(x)[1]


def atan2(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The angle of (x, y) in radians, in [-pi, pi]; atan2(0, 0) is 0, and -0 is 0 (unlike libm's)."""
    y = np.asarray(y, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    ax, ay = np.abs(x), np.abs(y)
    t = np.minimum(ax, ay)
    t /= np.maximum(np.maximum(ax, ay), _TINIEST)  # in [0, 1]; 0 / tiniest where both are 0
    k = np.searchsorted(_EDGE_A, t)  # how many midpoints lie below t: the nearest centre
    c = _CENTRE_A[k]
    u = (t - c) / (1.0 + t * c)
    z = u * u
    a = _ANGLE_A[k] + (u + u * z * _horner(z, _ATAN))
    a = np.where(ay > ax, _PIO2 - a, a)
    a = np.where(x < 0.0, _PI - a, a)
    return np.where(y < 0.0, -a, a)


def exp(x: np.ndarray) -> np.ndarray:
    """e**x of an array, float64 (0 below about -745, inf above about 709.8, as libm's)."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(all="ignore"):  # NaN and +-inf handled below; overflow to inf and underflow to 0 are the answer
        k = np.rint(x * _INV_LN2)
        r = (x - k * _LN2_1) - k * _LN2_2
        p = 1.0 + r * _horner(r, _EXP)
        out = np.ldexp(p, np.clip(np.nan_to_num(k), -2000, 2000).astype(np.int64))
    out = np.where(x == np.inf, np.inf, out)
    return np.where(x == -np.inf, 0.0, np.where(np.isnan(x), x, out))


def log(x: np.ndarray) -> np.ndarray:
    """The natural logarithm of an array, float64 (-inf at 0, NaN below, as libm's)."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(all="ignore"):  # 0, below 0, NaN and inf: handled at the end
        m, e = np.frexp(x)  # x = m * 2**e, m in [0.5, 1): exact
        low = m < _SQRT_HALF
        m = np.where(low, 2.0 * m, m)  # now in [sqrt(1/2), sqrt(2))
        e = np.where(low, e - 1, e).astype(np.float64)
        f = m - 1.0  # exact (Sterbenz)
        s = f / (2.0 + f)
        z = s * s
        two_s = 2.0 * s
        out = (e * _LN2_2 + (two_s + two_s * z * _horner(z, _LOG))) + e * _LN2_1
    out = np.where(x > 0.0, out, np.where(x == 0.0, -np.inf, np.nan))
    return np.where(x == np.inf, np.inf, np.where(np.isnan(x), x, out))


def sincos_scalar(x: float) -> tuple[float, float]:
    """:func:`sincos` of one float, the same operations in the same order (numba compiles it for the kernels)."""
    k = np.rint(x * _TWO_OVER_PI)
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    z = r * r
    p = _SIN[7]
    for i in range(6, -1, -1):
        p = _SIN[i] + z * p
    s = r + r * z * p
    p = _COS[8]
    for i in range(7, -1, -1):
        p = _COS[i] + z * p
    c = 1.0 + z * p
    if r != r:  # x NaN or infinite: so is r, and its quadrant is meaningless
        return r, r
    q = int(k) & 3
    if q & 1:
        s, c = c, s
    return (-s if q & 2 else s), (-c if (q + 1) & 2 else c)


def atan2_scalar(y: float, x: float) -> float:
    """:func:`atan2` of one pair, the same operations in the same order (numba compiles it for the kernels)."""
    if x != x or y != y:
        return x + y  # NaN, as the array form gives
    ax, ay = abs(x), abs(y)
    t = min(ax, ay) / max(max(ax, ay), _TINIEST)
    k = 0
    while k < 4 and _EDGE[k] < t:
        k += 1
    c = _CENTRE[k]
    u = (t - c) / (1.0 + t * c)
    z = u * u
    p = _ATAN[7]
    for i in range(6, -1, -1):
        p = _ATAN[i] + z * p
    a = _ANGLE[k] + (u + u * z * p)
    if ay > ax:
        a = _PIO2 - a
    if x < 0.0:
        a = _PI - a
    return -a if y < 0.0 else a
