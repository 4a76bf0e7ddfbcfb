"""Counter-based random numbers for the perception model: batch-invariant and reproducible.

Every random number is a pure function of ``(seed, variant_key, step k, object j, stream)``:
the tuple is hashed with the SplitMix64 finaliser (Steele, Lea & Flood, "Fast splittable
pseudorandom number generators", OOPSLA 2014; the mixing constants of Vigna's
``splitmix64.c``), chained over the five counters. No generator object carries state, so a
variant draws the same numbers whether it runs alone or in a batch of 100,000, in any
order, on any number of workers. Uniforms take the top 53 bits; normals come from the
Box-Muller transform of two uniform streams.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
UIntArray = npt.NDArray[np.uint64]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_MASK64 = (1 << 64) - 1
_TWO_M53 = 2.0**-53

# Streams: one per use, so that switching one effect on or off never shifts another's draws.
STREAM_DETECTION = 0
STREAM_POSITION = 1  # and 2 (Box-Muller pair: x, y)
STREAM_VELOCITY = 3  # and 4 (Box-Muller pair: vx, vy)


def _mix(z: UIntArray) -> UIntArray:
    """SplitMix64 finaliser (bijective avalanche mix of a 64-bit word), element-wise."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def _word(value: int) -> np.uint64:
    return np.uint64(int(value) & _MASK64)


def variant_keys_u64(variant_keys: npt.ArrayLike) -> UIntArray:
    """Variant keys as uint64 [B] (integers; negative ones wrap modulo 2^64).

    Args:
        variant_keys: [B] integers identifying each variant (e.g. :func:`label_keys` of
            its label; never its position in a batch, which would break invariance).
    Returns:
        [B] uint64.
    """
    keys = np.asarray(variant_keys)
    if keys.ndim != 1:
        raise ValueError(f"variant_keys must be a 1-D array [B], got shape {keys.shape}")
    if keys.dtype.kind == "u":
        return keys.astype(np.uint64)
    if keys.dtype.kind == "i" or keys.size == 0:
        return keys.astype(np.int64).view(np.uint64)
    raise ValueError(f"variant_keys must be integers, got dtype {keys.dtype}")


def label_keys(labels: Sequence[object] | npt.ArrayLike) -> UIntArray:
    """Stable 64-bit perception keys of variants from their labels (names).

    The key of a label is the first 8 bytes (little-endian) of its BLAKE2b hash (UTF-8 of
    ``str(label)``): it depends on the variant's label only, not on its position in a
    batch, so a sweep variant (labelled by its variant id) draws the same random numbers in
    a sweep chunk of any size and in ``vei run`` of its written configuration. Labels that
    repeat in the given order get distinct keys: the n-th repeat (n >= 1) is hashed
    with the BLAKE2b salt n (the first occurrence with the default salt 0), so equally named variants of one batch still draw
    independent numbers (those are reproducible for the same batch, but a repeated label
    run alone is its first occurrence: give variants distinct labels to re-run them singly).

    Args:
        labels: [B] labels (any objects; ``str`` of each is hashed).
    Returns:
        [B] uint64 keys (pass as ``variant_keys``).
    """
    import hashlib

    seen: dict[str, int] = {}
    out = np.empty(len(labels), dtype=np.uint64)  # type: ignore[arg-type]
    for i, lab in enumerate(labels):  # type: ignore[arg-type]
        text = str(lab)
        n = seen.get(text, 0)
        seen[text] = n + 1
        salt = n.to_bytes(16, "little")  # n = 0: all zeros, BLAKE2b's default salt
        digest = hashlib.blake2b(text.encode("utf-8"), digest_size=8, salt=salt).digest()
        out[i] = int.from_bytes(digest, "little")
    return out


def counter_bits(
    seed: int, variant_keys: npt.ArrayLike, k: int, n_objects: int, stream: int
) -> UIntArray:
    """64 random bits per (variant, object): a hash of (seed, key_i, k, j, stream).

    Args:
        seed: the perception seed (any integer, taken modulo 2^64).
        variant_keys: [B] integer keys of the variants.
        k: step index (integer).
        n_objects: N, the objects are j = 0 .. N-1.
        stream: which use (``STREAM_*``).
    Returns:
        [B, N] uint64.
    """
    keys = variant_keys_u64(variant_keys)
    j = np.arange(int(n_objects), dtype=np.uint64)
    with np.errstate(over="ignore"):
        head = np.full(1, _word(seed), dtype=np.uint64)
        head = _mix(head + _GOLDEN)
        h = _mix((keys ^ head) + _GOLDEN)  # [B]
        h = _mix((h ^ _word(k)) + _GOLDEN)
        h = _mix((h ^ _word(stream)) + _GOLDEN)
        return _mix((h[:, None] ^ j[None, :]) + _GOLDEN)  # [B, N]


def counter_uniform(
    seed: int, variant_keys: npt.ArrayLike, k: int, n_objects: int, stream: int
) -> FloatArray:
    """Uniform numbers in [0, 1) with 53 random bits, per (variant, object).

    Args:
        As :func:`counter_bits`.
    Returns:
        [B, N] float64 in [0, 1).
    """
    bits = counter_bits(seed, variant_keys, k, n_objects, stream)
    return (bits >> np.uint64(11)).astype(np.float64) * _TWO_M53


def counter_normal_pair(
    seed: int, variant_keys: npt.ArrayLike, k: int, n_objects: int, stream: int
) -> tuple[FloatArray, FloatArray]:
    """Two independent standard normals per (variant, object), Box-Muller from two uniforms.

    Uses streams ``stream`` (radius, u1 in (0, 1]) and ``stream + 1`` (angle, u2 in [0, 1)):
    ``z0 = sqrt(-2 ln u1) cos(2 pi u2)``, ``z1 = sqrt(-2 ln u1) sin(2 pi u2)``.

    Args:
        As :func:`counter_bits`.
    Returns:
        (z0, z1), each [B, N] float64, mean 0 and standard deviation 1.
    """
    u1 = 1.0 - counter_uniform(seed, variant_keys, k, n_objects, stream)
    u2 = counter_uniform(seed, variant_keys, k, n_objects, stream + 1)
    r = np.sqrt(-2.0 * np.log(u1))
    angle = (2.0 * np.pi) * u2
    return r * np.cos(angle), r * np.sin(angle)
