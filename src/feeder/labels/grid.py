"""The fence configuration grid, the datasets and the splits.

Configurations (``configurations(config, part_ids)``, pure and seeded by ids):

* Grid: every location holds ``none``, a straight fence at one of ``fences.straight_angles`` or a
  curved fence at one of ``fences.curved_angles``; a configuration is a (Location 1, Location 2)
  pair whose type combination (``<type1>_<type2>``) is listed in ``fences.combos``. The default
  list leaves out ``none_none``: with no fence the final yaw is the uniform initial yaw, which
  teaches a model nothing about fences.
* Parts dataset: ``datasets.holdout_parts`` (or, when that list is empty, the
  ``datasets.n_holdout`` parts ranked first by sha256(seed:holdout:id)); each gets
  ``datasets.parts_per_part`` configurations drawn from the configurations used in Main
  (unseen parts, known fences).
* Fences dataset: ``datasets.fences_parts`` Main parts (ranked by sha256(seed:fences:id)); each is
  given one reserved type combination from ``fences.reserved_combos`` (round robin). That part's
  Main configurations never use that combination; its Fences configurations all do.
  ``datasets.fences_samples`` configurations are spread over those parts.
* Main: every other part gets ``fences.main_per_part`` configurations, spread evenly over its
  allowed type combinations (remainder to a seeded choice of combinations), angles drawn without
  replacement. ``split`` is ``train``/``test`` by a random row split of the Main rows
  (``datasets.test_fraction``, ``datasets.split_seed``), ``fences`` and ``parts`` otherwise.
* Wide dataset (the wider library): parts whose id matches a pattern of ``datasets.wide.parts``
  (shell patterns) stay out of the three datasets above, which are built from the other parts
  alone (so adding wide parts changes none of their rows). Each gets ``datasets.wide.per_part``
  configurations drawn as Main's are, over every type combination; split ``wide``. They serve the
  leave-parts-out GroupKFold, which runs over every part.

Seeds derive from ``fences.seed`` and the part id, so adding a part never changes another part's
configurations. The workflow calls :func:`configurations` at parse time: this module imports no
more than numpy, pandas and :mod:`feeder.lane.fences`.
"""

from __future__ import annotations

import fnmatch
import hashlib
import itertools
import math
from functools import lru_cache

import numpy as np
import pandas as pd

from feeder.errors import FeederError
from feeder.lane.fences import TYPES, Fence, config_id, parse_config_id

DATASETS = ("main", "fences", "parts", "wide")
PROTOCOL_SPLITS = ("train", "test", "fences", "parts")  # the paper's Main/Fences/Parts protocol
WIDE = "wide"  # the wider library's dataset and split: in the GroupKFold only
SPLITS = (*PROTOCOL_SPLITS, WIDE)


def hash_seed(*tokens) -> int:
    """A 64-bit seed from sha256 of the tokens joined by ``:`` (stable across runs and machines)."""
    digest = hashlib.sha256(":".join(str(t) for t in tokens).encode()).digest()
    return int.from_bytes(digest[:8], "little")


def _rank(parts, *tokens) -> list[str]:
    return sorted(parts, key=lambda p: (hash_seed(*tokens, p), p))


def _angles(fences: dict, kind: str) -> list[float]:
    if kind == "none":
        return [0.0]
    values = fences[f"{kind}_angles"]
    return [float(a) for a in values]


def combo_grid(fences: dict, combo: str) -> list[str]:
    """Every configuration id of one type combination ``<type1>_<type2>`` on the angle grid."""
    t1, t2 = _split_combo(combo)
    return list(_grid(t1, tuple(_angles(fences, t1)), t2, tuple(_angles(fences, t2))))


@lru_cache(maxsize=64)
def _grid(t1: str, angles1: tuple, t2: str, angles2: tuple) -> tuple[str, ...]:
    first = [Fence(t1, a) for a in angles1]
    second = [Fence(t2, a) for a in angles2]
    return tuple(config_id(f1, f2) for f1, f2 in itertools.product(first, second))


def _split_combo(combo: str) -> tuple[str, str]:
    t = combo.split("_")
    if len(t) != 2 or t[0] not in TYPES or t[1] not in TYPES:
        raise FeederError(f"fence type combination {combo!r} is not <type>_<type> with types {TYPES}")
    return t[0], t[1]


def _sample_main(fences: dict, part: str, combos: list[str], n: int, token: str = "main") -> list[str]:
    rng = np.random.default_rng(hash_seed(fences["seed"], token, part))
    base, rem = divmod(n, len(combos))
    extra = set(rng.permutation(len(combos))[:rem].tolist())
    chosen = []
    for i, combo in enumerate(combos):
        grid = combo_grid(fences, combo)
        k = min(base + (i in extra), len(grid))
        chosen += [grid[j] for j in sorted(rng.choice(len(grid), size=k, replace=False))]
    return chosen


def random_test_rows(n: int, test_fraction: float, seed: int) -> np.ndarray:
    """Row indices of a random test split, identical to sklearn's
    ``train_test_split(range(n), test_size=test_fraction, random_state=seed)`` test part
    (ceil(test_fraction * n) rows from ``RandomState(seed).permutation(n)``), without importing
    sklearn at workflow parse time."""
    n_test = int(math.ceil(test_fraction * n))
    if not 0 < n_test < n:
        raise FeederError(f"datasets.test_fraction={test_fraction} leaves no train or no test row of {n}")
    return np.random.RandomState(seed).permutation(n)[:n_test]


def wide_parts(config: dict, part_ids) -> list[str]:
    """The wide-dataset parts: those whose id matches a shell pattern of ``datasets.wide.parts``."""
    wide = config["datasets"].get("wide") or {}
    patterns = [str(p) for p in wide.get("parts") or ()]
    return sorted(p for p in set(part_ids) if any(fnmatch.fnmatchcase(p, pat) for pat in patterns))


def protocol_parts(config: dict, part_ids) -> list[str]:
    """``part_ids`` (in their order) without the wide-dataset parts: the paper's protocol."""
    wide = set(wide_parts(config, part_ids))
    return [p for p in part_ids if p not in wide]


def holdout_parts(config: dict, part_ids) -> list[str]:
    """The Parts-dataset parts: the configured list, or the seeded hash-ranked first n_holdout."""
    ds = config["datasets"]
    parts = sorted(set(part_ids))
    listed = list(ds.get("holdout_parts") or [])
    if listed:
        missing = [p for p in listed if p not in parts]
        if missing:
            raise FeederError(
                f"datasets.holdout_parts names unknown parts or parts of the wider library: {', '.join(missing)}"
            )
        return sorted(listed)
    return sorted(_rank(parts, config["fences"]["seed"], "holdout")[: int(ds["n_holdout"])])


def _fence_parts(config: dict, main_parts: list[str]) -> dict[str, str]:
    """The Fences-dataset parts, each with its reserved type combination (round robin)."""
    fences, ds = config["fences"], config["datasets"]
    reserved = list(fences["reserved_combos"])
    n_fp = int(ds["fences_parts"])
    if n_fp > len(main_parts):
        raise FeederError(f"datasets.fences_parts={n_fp} exceeds the {len(main_parts)} Main parts")
    if n_fp and not reserved:
        raise FeederError("datasets.fences_parts > 0 needs fences.reserved_combos")
    fence_parts = _rank(main_parts, fences["seed"], "fences")[:n_fp]
    return {p: reserved[i % len(reserved)] for i, p in enumerate(fence_parts)}


def _assign_splits(df: pd.DataFrame, ds: dict) -> pd.Series:
    """``train``/``test`` by a random row split of the Main rows, the dataset name otherwise."""
    split = df["dataset"].astype(object).copy()
    main_idx = np.flatnonzero(df["dataset"].to_numpy() == "main")
    split.iloc[main_idx] = "train"
    if main_idx.size >= 2:
        test = random_test_rows(main_idx.size, float(ds["test_fraction"]), int(ds["split_seed"]))
        split.iloc[main_idx[test]] = "test"
    return split


def configurations(config: dict, part_ids) -> pd.DataFrame:
    """Every simulated (part, fence configuration) with its dataset and split (see module doc).

    Columns: part, config_id, loc1, loc2 (command-line fence specs), dataset (main/fences/parts/wide),
    split (train/test/fences/parts/wide). Rows are sorted by dataset, part, config_id.
    """
    fences, ds = config["fences"], config["datasets"]
    parts = sorted(set(part_ids))
    combos = list(fences["combos"])
    for c in combos + list(fences["reserved_combos"]):
        _split_combo(c)
    if not set(fences["reserved_combos"]) <= set(combos):
        raise FeederError("fences.reserved_combos must be listed in fences.combos")
    wide = wide_parts(config, parts)
    protocol = protocol_parts(config, parts)
    held = holdout_parts(config, protocol)
    main_parts = [p for p in protocol if p not in held]
    if not main_parts:
        raise FeederError("no parts left for the Main dataset after the holdout and wide parts")
    reserved_of = _fence_parts(config, main_parts)
    fence_parts = list(reserved_of)

    rows = []
    for p in main_parts:
        allowed = [c for c in combos if c != reserved_of.get(p)]
        rows += [(p, cid, "main") for cid in _sample_main(fences, p, allowed, int(fences["main_per_part"]))]
    known = sorted({cid for _, cid, _ in rows})
    n_fs, n_fp = int(ds["fences_samples"]), len(fence_parts)
    for i, p in enumerate(fence_parts):
        k = n_fs // n_fp + (i < n_fs % n_fp)
        grid = combo_grid(fences, reserved_of[p])
        rng = np.random.default_rng(hash_seed(fences["seed"], "fences", p))
        take = sorted(rng.choice(len(grid), size=min(k, len(grid)), replace=False))
        rows += [(p, grid[j], "fences") for j in take]
    for p in held:
        rng = np.random.default_rng(hash_seed(fences["seed"], "parts", p))
        take = sorted(rng.choice(len(known), size=min(int(ds["parts_per_part"]), len(known)), replace=False))
        rows += [(p, known[j], "parts") for j in take]
    per_wide = int((ds.get("wide") or {}).get("per_part", 0))
    if wide and per_wide < 1:
        raise FeederError(f"datasets.wide.parts matches {len(wide)} parts but datasets.wide.per_part is {per_wide}")
    for p in wide:
        rows += [(p, cid, WIDE) for cid in _sample_main(fences, p, combos, per_wide, token=WIDE)]

    df = pd.DataFrame(rows, columns=["part", "config_id", "dataset"])
    locs = [parse_config_id(c) for c in df["config_id"]]
    df["loc1"] = [a.spec for a, _ in locs]
    df["loc2"] = [b.spec for _, b in locs]
    order = {d: i for i, d in enumerate(DATASETS)}
    df = df.sort_values(["dataset", "part", "config_id"], key=lambda s: s.map(order) if s.name == "dataset" else s)
    df = df.reset_index(drop=True)
    df["split"] = _assign_splits(df, ds)
    return df[["part", "config_id", "loc1", "loc2", "dataset", "split"]]
