"""'%.17g' for whole blocks of doubles at NumPy speed, byte for byte Python's text.

The CSV writers use the compiled formatter (`symid.output.compiled_csv`, the
same method in C) and this one when no C compiler is at hand.

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
to Python. Integer values below 1e16 are exact integers already; zeros are
'0' or '-0'; values outside the range, inf and nan go to Python too.
The text is then put together in 8-byte words: the digits by SWAR
arithmetic, the '.', the leading '0.000' and the sign by shifts and masks.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from symid.backends import Array

_LOW, _HIGH = 1e-250, 1e250


def powers_of_ten(start: int, stop: int) -> tuple[list[float], list[float]]:
    """10^s = hi + lo for s in [start, stop): hi the nearest double, lo the
    nearest double to the rest (together exact to ~2^-106)."""
    exact = [Fraction(10) ** s for s in range(start, stop)]
    hi = [float(e) for e in exact]
    return hi, [float(e - Fraction(h)) for e, h in zip(exact, hi)]


_S = np.arange(-240, 276)  # the powers 16 - K needed for K in [-251, 250]
_P_HI, _P_LO = (np.array(t) for t in powers_of_ten(int(_S[0]), int(_S[-1]) + 1))
_SPLIT = 134217729.0  # 2^27 + 1: Veltkamp's splitter for a product without FMA
_MARGIN = 1e-9  # far above the 1e-12 the product can be off
_P10 = 10.0 ** np.arange(17)

# A value's text is [sign and body][exponent, separator] in 32 bytes whose
# unused bytes are 0 and dropped at the end. The body is the 17 digits with
# a '.' put in (and '0.000' before them for K in [-4, -1]), cut after the
# last significant digit as %g does.


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
WORDS = 4  # a value's text as 8-byte words: 24 bytes of sign and body, then exponent and separator
_ALL = np.uint64(2**64 - 1)
_MASKS = np.array([(1 << (8 * c)) - 1 for c in range(9)], dtype=np.uint64)  # the c low bytes
_DOTS = np.uint64(0x2E2E2E2E2E2E2E2E)
_ZEROS = np.uint64(0x3030303030303030)


def _swar8(x: Array) -> Array:
    """The 8 decimal digits of x < 10^8 as bytes (values 0-9) of a uint64,
    the most significant in the lowest byte: lanes split 4|4, 2|2, 1|1."""
    x = x.astype(np.uint64)
    high = x // np.uint64(10000)
    v = high | ((x - high * np.uint64(10000)) << np.uint64(32))
    t = ((v * np.uint64(10486)) >> np.uint64(20)) & np.uint64(0x0000007F0000007F)  # y // 100, y < 10^4
    v = t | ((v - t * np.uint64(100)) << np.uint64(16))
    t = ((v * np.uint64(103)) >> np.uint64(10)) & np.uint64(0x000F000F000F000F)  # z // 10, z < 100
    return t | ((v - t * np.uint64(10)) << np.uint64(8))  # type: ignore[no-any-return]


def _top_byte(w: Array) -> Array:
    """Index (0-7) of the highest nonzero byte of each word (-64 for 0); the bytes
    are digits < 16, so the double nearest w never reaches the next byte."""
    exponent = np.frexp(w.astype(float))[1]
    return np.where(w == 0, -64, (exponent - 1) // 8)  # type: ignore[no-any-return]


def _shift_up(words: list[Array], nbytes: Array) -> list[Array]:
    """The string of 3 words moved nbytes (0-7) further, 0 bytes coming in at the start."""
    up = np.uint64(8) * nbytes.astype(np.uint64)
    down = np.uint64(63) - up  # two steps: a shift by 64 is undefined
    carry = [np.zeros_like(words[0]), *((w >> np.uint64(1)) >> down for w in words[:-1])]
    return [(w << up) | c for w, c in zip(words, carry)]


def _shift_one(words: list[Array]) -> list[Array]:
    """The string of 3 words moved one byte further (a shift by a constant: fast)."""
    eight, back = np.uint64(8), np.uint64(56)
    return [words[0] << eight, (words[1] << eight) | (words[0] >> back), (words[2] << eight) | (words[1] >> back)]


def fields(values: Array, out: np.ndarray | None = None) -> np.ndarray:
    """Each value's '%.17g' text in WORDS words, unused bytes 0.

    Args:
        values: float64, any shape.
        out: zeroed uint64 of shape (values.size, WORDS) to write into.

    Returns:
        out, or a new array of shape (values.size, WORDS).
    """
    v = np.ascontiguousarray(values, dtype=float).ravel()
    if out is None:
        out = np.zeros((v.size, WORDS), np.uint64)
    with np.errstate(invalid="ignore", over="ignore"):  # inf and nan go to Python's % anyway
        for start in range(0, v.size, PIECE):
            _fields(v[start:start + PIECE], out[start:start + PIECE])
    return out


def _fields(v: Array, out: np.ndarray) -> None:
    """`fields` of one piece, into out (shape (v.size, WORDS); its last word's top byte is kept).

    The text is built in 8-byte words (little-endian: byte i of the text is
    bits 8i..8i+7): inserting the '.' and the sign are shifts and masks.
    """
    x = np.abs(v)
    n, k, sure = _decimal(x)
    zero = x == 0
    n[zero] = 0
    # the 17 digits: a lead digit, then 8 and 8 (digit values, not yet ASCII)
    lead = n // 10**16
    rest = n - lead * 10**16
    high = rest // 10**8
    first, second = _swar8(high), _swar8(rest - high * 10**8)
    eight = np.uint64(8)
    text = [lead.astype(np.uint64) | (first << eight), (first >> np.uint64(56)) | (second << eight),
            second >> np.uint64(56)]
    top = np.maximum(np.maximum(_top_byte(text[0]), 8 + _top_byte(text[1])), 16 + _top_byte(text[2]))
    nsig = np.maximum(top + 1, 1)  # trailing zeros dropped, as %g does
    text = [w | _ZEROS for w in text]
    text[2] &= _MASKS[1]
    sci = (k < -4) | (k > 16)
    small = ~sci & (k < 0)
    lead_zeros = np.where(small, -k, 0)  # 0.000ddd is 0.ddd of the digits after -K zeros
    some = np.flatnonzero(small)
    if some.size:
        zeros = lead_zeros[some]
        for w, word in enumerate(_shift_up([t[some] for t in text], zeros)):
            text[w][some] = word
        text[0][some] |= _MASKS[zeros] & _ZEROS
    nsig = nsig + lead_zeros
    dot = np.where(~sci & (k >= 0), k + 1, 1)
    length = np.where(nsig > dot, nsig + 1, dot)
    moved = _shift_one(text)
    body = []
    for w in range(3):
        before = _MASKS[np.clip(dot - 8 * w, 0, 8)]  # the bytes before the '.'
        through = _MASKS[np.clip(dot + 1 - 8 * w, 0, 8)]  # and the '.'
        word = (text[w] & before) | (moved[w] & ~through) | ((through ^ before) & _DOTS)
        body.append(word & _MASKS[np.clip(length - 8 * w, 0, 8)])
    body[0] = np.where(zero, np.uint64(0x30), body[0])
    body[1] = np.where(zero, np.uint64(0), body[1])
    body[2] = np.where(zero, np.uint64(0), body[2])
    negative = np.signbit(v)
    signed = _shift_one(body)
    signed[0] |= np.uint64(ord("-"))
    body = [np.where(negative, a, b) for a, b in zip(signed, body)]
    for w in range(3):
        out[:, w] = body[w]
    at = np.flatnonzero(sci & sure)
    if at.size:
        e = k[at]
        mag = np.abs(e)
        three = mag >= 100
        d0 = np.where(three, mag // 100, mag // 10)
        d1 = np.where(three, mag // 10 % 10, mag % 10)
        d2 = np.where(three, mag % 10 + 48, 0)
        exp = (ord("e") | (np.where(e < 0, ord("-"), ord("+")) << 8) | ((d0 + 48) << 16) | ((d1 + 48) << 24)
               | (d2 << 32)).astype(np.uint64)
        out[at, 3] = (out[at, 3] & ~_MASKS[7]) | exp
    for i in np.flatnonzero(~(sure | zero)):  # Python's own text: rare values and ties
        raw = ("%.17g" % float(v[i])).encode().ljust(24, b"\0")
        out[i, :3] = np.frombuffer(raw, np.uint64)


def csv_block(block: Array) -> bytes:
    """A block of rows (shape (rows, width)) as CSV lines, each '%.17g'
    joined by ',' and ended by a newline: `format_row` for every row, at once."""
    rows, width = block.shape
    words = np.zeros((rows, width, WORDS), np.uint64)
    words[:, :, 3] = np.uint64(ord(",")) << np.uint64(56)
    words[:, -1, 3] = np.uint64(ord("\n")) << np.uint64(56)
    fields(block, words.reshape(rows * width, WORDS))
    flat = words.view(np.uint8).ravel()
    return flat[flat != 0].tobytes()
