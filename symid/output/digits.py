"""'%.17g' for whole blocks of doubles at NumPy speed, byte for byte Python's text.

Python formats a double with `'%.17g' % x` in about a microsecond; a table of
a million instants of 67 columns is 67 million of them. Here a block is
formatted with array operations, and every value whose text this cannot
vouch for goes through Python's `%` itself, so the text is always exactly
Python's (which reads back as the same double).

How: for x = |value| in [1e-250, 1e250], K = floor(log10 x) and the 17
significant digits N = round(x * 10^(16 - K)) come from a double-double
product with 10^(16 - K) (a table exact to ~2^-106). The product is within
1e-12 of the exact x * 10^(16 - K); a value whose fraction lies within 1e-9
of a rounding decision (a tie, or a power of ten at the K boundary) is left
to Python. Integer values below 1e16 are exact integers already. Zeros,
values outside the range, inf and nan go to Python too.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from symid.backends import Array

_LOW, _HIGH = 1e-250, 1e250
_S = np.arange(-240, 276)  # the powers 16 - K needed for K in [-251, 250]
_EXACT = [Fraction(10) ** int(s) for s in _S]
_P_HI = np.array([float(e) for e in _EXACT])
_P_LO = np.array([float(e - Fraction(h)) for e, h in zip(_EXACT, _P_HI)])
_SPLIT = 134217729.0  # 2^27 + 1: Veltkamp's splitter for a product without FMA
_MARGIN = 1e-9  # far above the 1e-12 the product can be off
_P10 = 10.0 ** np.arange(17)

# A value's text is [sign][body][exponent], fixed-width fields whose unused
# bytes are 0 and dropped at the end. The body is the 17 digits with a '.'
# put in (and '0.000' before them for K in [-4, -1]), cut after the last
# significant digit as %g does.
BODY = 22  # '0.000' and 17 digits
FIELD = 1 + BODY + 5  # sign, body, 'e-250'


_POS = np.arange(BODY, dtype=np.uint8)



_ASCII_0, _ASCII_DOT = np.uint8(48), np.uint8(46)


def _blend(mask: Array, a: Array | np.uint8, b: Array) -> Array:
    """np.where(mask, a, b) for uint8 rows."""
    return b + mask * (a - b)  # type: ignore[no-any-return]


def _two_prod(a: Array, b: Array) -> tuple[Array, Array]:
    """p + e == a * b exactly (Dekker), for products far from overflow and underflow."""
    p = a * b
    c = _SPLIT * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLIT * b
    bh = c - (c - b)
    bl = b - bh
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


def _digits(x: Array, k: Array) -> tuple[Array, Array]:
    """(N rounded to an integer, signed fraction N_exact - N) of x * 10^(16 - k)."""
    at = 16 - _S[0] - k
    p, e = _two_prod(x, _P_HI[at])
    t = e + x * _P_LO[at]
    whole = np.floor(p)
    t += p - whole  # exact: the fraction of a double
    near = np.rint(t)
    return whole.astype(np.int64) + near.astype(np.int64), t - near


def _decimal(x: Array) -> tuple[Array, Array, Array]:
    """(N, K, sure) for x >= 0: x ~ N * 10^(K - 16), 10^16 <= N < 10^17,
    N correctly rounded where sure (never for 0, inf, nan or out of range)."""
    inside = (x >= _LOW) & (x <= _HIGH)
    xs = np.where(inside, x, 1.5)
    k = np.floor(np.log10(xs)).astype(np.int64)
    n, f = _digits(xs, k)
    for _ in range(3):  # log10 may be one off near a power of ten: redo those
        low = (n < 10**16) | ((n == 10**16) & (f < 0))
        high = (n > 10**17) | ((n == 10**17) & (f >= 0))
        wrong = np.flatnonzero(low | high)
        if not wrong.size:
            break
        k[wrong] += high[wrong].astype(np.int64) - low[wrong]
        n[wrong], f[wrong] = _digits(xs[wrong], k[wrong])
    carry = n == 10**17  # rounded up to the next power of ten
    if carry.any():
        n[carry] = 10**16
        k[carry] += 1
    af = np.abs(f)
    # a tie, or a value at a power of ten whose side the product cannot tell
    sure = inside & (af < 0.5 - _MARGIN) & ~(((n == 10**16) | carry) & (af < _MARGIN))
    if wrong.size:
        sure[wrong] = False
    whole = (x == np.floor(x)) & (x < 1e16) & (x > 0)
    if whole.any():  # integers below 10^16 are exact already: 1, 2.5e3, counts
        xi = x[whole]
        ki = np.searchsorted(_P10, xi, side="right") - 1
        k[whole] = ki
        n[whole] = xi.astype(np.int64) * (10 ** (16 - ki))
        sure[whole] = True
    return n, k, sure


PIECE = 8192  # values formatted at once: the temporaries stay in cache


def fields(values: Array, out: np.ndarray | None = None) -> np.ndarray:
    """Each value's '%.17g' text as a FIELD-byte row, unused bytes 0.

    Args:
        values: float64, any shape.
        out: zeroed uint8 of shape (values.size, >= FIELD) to write into.

    Returns:
        out, or a new array of shape (values.size, FIELD).
    """
    v = np.ascontiguousarray(values, dtype=float).ravel()
    if out is None:
        out = np.zeros((v.size, FIELD), np.uint8)
    with np.errstate(invalid="ignore", over="ignore"):  # inf and nan go to Python's % anyway
        for start in range(0, v.size, PIECE):
            _fields(v[start:start + PIECE], out[start:start + PIECE, :FIELD])
    return out


def _fields(v: Array, out: np.ndarray) -> None:
    """`fields` of one piece, into out (zeroed, shape (v.size, FIELD)).

    The text is built position by position over all values (rows of shape
    (size,)): NumPy is fast over long rows, slow over 22-byte ones.
    """
    x = np.abs(v)
    n, k, sure = _decimal(x)
    zero = x == 0
    n[zero] = 0
    size = v.size
    # the 17 digits as rows: a lead digit, then 8 pairs; rows 17.. are 0 bytes
    digit = np.zeros((BODY, size), np.uint8)
    lead = n // 10**16
    digit[0] = lead
    rest = n - lead * 10**16
    high = rest // 10**8
    for half, first in ((high, 1), (rest - high * 10**8, 9)):
        q = half.astype(np.int32)
        for j in range(first + 6, first - 1, -2):
            q, r = np.divmod(q, 100)
            tens = (r * 205) >> 11  # r // 10 for r < 100, without a division
            digit[j], digit[j + 1] = tens, r - 10 * tens
    digit[:17] += 48
    nsig = np.ones(size, np.uint8)  # trailing zeros dropped
    for j in range(1, 17):
        np.maximum(nsig, (digit[j] != 48) * np.uint8(j + 1), out=nsig)
    sci = (k < -4) | (k > 16)
    small = ~sci & (k < 0)
    some = np.flatnonzero(small)
    if some.size:
        # 0.000ddd is 0.ddd of the digits with -K zeros before them: shift them
        zeros = -k[some]
        sub = digit[:, some]
        moved = np.full_like(sub, 48)
        for z in range(1, 5):
            group = np.flatnonzero(zeros == z)
            moved[z:z + 17, group] = sub[:17, group]
            moved[z + 17:, group] = 0
        digit[:, some] = moved
        nsig[some] += zeros.astype(np.uint8)
        k = np.where(small, 0, k)
    whole = ~sci & (k >= 0)
    dot = np.where(whole, k + 1, 1).astype(np.uint8)
    length = np.where(whole, np.where(nsig > k + 1, nsig + 1, k + 1), nsig + (nsig > 1)).astype(np.uint8)
    length[zero] = 1
    body = np.empty((BODY, size), np.uint8)
    for p in range(BODY):
        # the digit at p: digit p before the '.', p - 1 after it; a blend
        # b + m * (a - b) (uint8, mod 256) is 3x faster than np.where here
        row = _blend(p < dot, digit[p], digit[max(p - 1, 0)])
        row = _blend(dot == p, _ASCII_DOT, row)
        np.multiply(row, p < length, out=body[p])
    out[:, 1:1 + BODY] = body.T
    out[:, 0] = np.signbit(v) * ord("-")
    at = np.flatnonzero(sci & sure)
    if at.size:
        e = k[at]
        mag = np.abs(e)
        exp = np.zeros((at.size, 5), np.uint8)
        exp[:, 0] = ord("e")
        exp[:, 1] = np.where(e < 0, ord("-"), ord("+"))
        three = mag >= 100
        exp[:, 2] = np.where(three, mag // 100 + 48, mag // 10 + 48)
        exp[:, 3] = np.where(three, mag // 10 % 10 + 48, mag % 10 + 48)
        exp[:, 4] = np.where(three, mag % 10 + 48, 0)
        out[at, 1 + BODY:] = exp
    for i in np.flatnonzero(~(sure | zero)):  # Python's own text: rare values and ties
        text = ("%.17g" % float(v[i])).encode()
        out[i] = 0
        out[i, :len(text)] = np.frombuffer(text, np.uint8)


def csv_block(block: Array) -> bytes:
    """A block of rows (shape (rows, width)) as CSV lines, each '%.17g'
    joined by ',' and ended by a newline: `format_row` for every row, at once."""
    rows, width = block.shape
    text = np.zeros((rows, width, FIELD + 1), np.uint8)
    fields(block, text.reshape(rows * width, FIELD + 1))
    text[:, :, FIELD] = ord(",")
    text[:, -1, FIELD] = ord("\n")
    flat = text.ravel()
    return flat[flat != 0].tobytes()
