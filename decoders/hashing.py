"""Fibonacci hashing, for the numpy paths that hash 64-bit keys.

Multiplying a key by 2**64 / φ (rounded to odd; Knuth's multiplier), wrapping, spreads
every bit of it over the product's top bits: keys whose low bits cluster (a frame's CRC,
a digest) still spread over a table indexed by the top bits.
"""

from __future__ import annotations

import numpy as np

#: 2**64 / φ, odd, as the unsigned 64-bit multiplier.
FIBONACCI = np.uint64(0x9E3779B97F4A7C15)
#: The same bits as a signed multiplier, for int64 keys (the product wraps alike).
FIBONACCI_SIGNED = FIBONACCI.view(np.int64)
