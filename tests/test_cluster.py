"""A real SLURM run: the smoke workflow's simulations and dataset through ``profiles/slurm-local``
(Snakemake's SLURM executor, simulations as job arrays) on the one-node cluster of
``profiles/slurm-local/up.sh`` equal a local run's.

Runs whenever the cluster can be brought up (root and Debian's slurm-wlm/munge, installed by the
script when missing); skipped otherwise, unless ``FEEDER_REQUIRE_CLUSTER=1`` (CI sets it), which
turns a cluster that does not come up into a failure. ``FEEDER_CLUSTER_LOG=FILE`` keeps the SLURM
run's Snakemake log there (``make test-cluster`` keeps it in ``results/cluster/``).
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from workflow_helpers import ROOT, SNAKEMAKE, merged_config, scratch_copy

pytestmark = pytest.mark.slow

UP = ROOT / "profiles" / "slurm-local" / "up.sh"
# The smoke workflow's 28 jobs (features, 20 simulations, configurations, labels), each simulation
# with the adaptive design's first round of yaws only (2-4 s a job): what is tested is the route
# through SLURM (array jobs, then the jobs that read their files), not the labels. The overlay is
# written into both scratch copies.
OVERLAY = "cluster_test.yaml"
SMOKE = ("--configfile", "config/smoke.yaml", OVERLAY)
TARGET = "results/smoke/datasets/dataset.npz"
TIMING_KEYS = {"wall_s", "cpu_s"}  # measured, so different on every run
RUN_TIMEOUT_S = 1800
UP_TIMEOUT_S = 900


@pytest.fixture(scope="module")
def cluster() -> None:
    required = os.environ.get("FEEDER_REQUIRE_CLUSTER") == "1"
    try:
        proc = subprocess.run([str(UP)], capture_output=True, text=True, timeout=UP_TIMEOUT_S)
        reason = proc.stderr.strip()[-500:] if proc.returncode else ""
    except (OSError, subprocess.TimeoutExpired) as exc:
        reason = str(exc)
    if reason:
        if required:
            pytest.fail(f"FEEDER_REQUIRE_CLUSTER=1 but the SLURM cluster did not come up: {reason}")
        pytest.skip(f"no SLURM cluster could be brought up here: {reason}")


def _run(work: Path, *args: str) -> subprocess.CompletedProcess:
    first_round = merged_config(ROOT, "config/smoke.yaml")["sim"]["adaptive"]["n0"]
    (work / OVERLAY).write_text(f"sim:\n  drops: {int(first_round)}\n")
    return subprocess.run(
        [SNAKEMAKE, *args, *SMOKE, "--", TARGET], cwd=work, capture_output=True, text=True, timeout=RUN_TIMEOUT_S
    )


def _arrays(path: Path) -> dict[str, object]:
    with np.load(path, allow_pickle=False) as z:
        out = {}
        for key in z.files:
            if key in TIMING_KEYS:
                continue
            value = z[key]
            if key == "meta":
                meta = json.loads(str(value))
                value = {k: v for k, v in meta.items() if k not in TIMING_KEYS}
            out[key] = value
        return out


def _assert_same(a: dict, b: dict, name: str) -> None:
    assert a.keys() == b.keys(), name
    for key in a:
        if isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key], err_msg=f"{name}: {key}")
        else:
            assert a[key] == b[key], f"{name}: {key}"


def test_smoke_simulations_through_slurm_equal_a_local_run(cluster, tmp_path):
    local = scratch_copy(tmp_path / "local")
    proc = _run(local, "--cores", "2")
    assert proc.returncode == 0, proc.stderr[-3000:]

    remote = scratch_copy(tmp_path / "slurm")
    proc = _run(remote, "--profile", "profiles/slurm-local")
    if keep := os.environ.get("FEEDER_CLUSTER_LOG"):
        Path(keep).parent.mkdir(parents=True, exist_ok=True)
        Path(keep).write_text(proc.stderr)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # the jobs really went through SLURM, the simulations as arrays
    assert "has been submitted with SLURM jobid" in proc.stderr
    logs = remote / ".snakemake" / "slurm_logs"
    assert list((logs / "rule_simulate").rglob("*.log")), "no SLURM log of a simulation job"
    assert "array" in proc.stderr.lower()

    sims = sorted(p.relative_to(local) for p in (local / "results" / "smoke" / "sim").rglob("*.npz"))
    assert sims, "the local run simulated nothing"
    assert sims == sorted(p.relative_to(remote) for p in (remote / "results" / "smoke" / "sim").rglob("*.npz"))
    for rel in sims:
        _assert_same(_arrays(local / rel), _arrays(remote / rel), str(rel))
    _assert_same(_arrays(local / TARGET), _arrays(remote / TARGET), TARGET)
