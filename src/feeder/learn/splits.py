"""Seeded splits of the structured protocol (pure), shared with the gated neighbour
(:mod:`feeder.learn.neighbour`), which scores on the protocol's own Main re-splits: a seed derived
from the base seed and ids, the locked and validation parts ranked by a hash (stable when parts are
added), and seeded re-splits of rows."""

from __future__ import annotations

import hashlib

import numpy as np

from feeder.errors import FeederError

SEED_MOD = 2**31 - 1


def derived_seed(base: int, *ids) -> int:
    """A seed from the base seed and ids: sha256 of ``base:id1:id2...`` modulo 2³¹ − 1."""
    text = ":".join(map(str, (int(base), *ids)))
    return int(hashlib.sha256(text.encode()).hexdigest(), 16) % SEED_MOD


def ranked_parts(parts, seed: int, what: str) -> list[str]:
    """The distinct parts ordered by sha256(``seed:what:part``) (stable when parts are added)."""
    names = sorted(set(map(str, parts)))
    return sorted(names, key=lambda p: hashlib.sha256(f"{seed}:{what}:{p}".encode()).hexdigest())


def pick_parts(parts, fraction: float, seed: int, what: str) -> set[str]:
    """``round(fraction · parts)`` of the distinct parts, at least one and at least one left,
    the first of :func:`ranked_parts`."""
    ranked = ranked_parts(parts, seed, what)
    if len(ranked) < 2:
        raise FeederError(f"{what}: need at least 2 parts, got {len(ranked)}")
    if not 0.0 < fraction < 1.0:
        raise FeederError(f"{what}: fraction {fraction} must lie in (0, 1)")
    n = int(min(max(1, round(fraction * len(ranked))), len(ranked) - 1))
    return set(ranked[:n])


def resplit_rows(rows, fraction: float, seed: int) -> np.ndarray:
    """Sorted ``round(fraction · len(rows))`` of ``rows`` (at least one), a seeded permutation."""
    rows = np.asarray(rows)
    n = int(min(max(1, round(fraction * rows.size)), rows.size - 1))
    return np.sort(np.random.default_rng(seed).permutation(rows)[:n])
