import json
import os
import sys

import pytest

from feeder.errors import FeederError
from feeder.workflow import (
    cli_options,
    code_inputs,
    code_modules,
    feeder_imports,
    module_file,
    put_interpreter_on_path,
    select_settings,
)


def test_select_settings_keeps_nesting_and_only_the_named_keys():
    config = {"sim": {"drops": 50, "min_ok_drops": 20, "presets": {"fast": {}}}, "labels": {"bins": 360}}
    picked = json.loads(select_settings(config, "sim.min_ok_drops", "labels"))
    assert picked == {"sim": {"min_ok_drops": 20}, "labels": {"bins": 360}}
    # the same settings in another order give the same string (a stable rerun trigger)
    assert select_settings(config, "labels", "sim.min_ok_drops") == select_settings(
        config, "sim.min_ok_drops", "labels"
    )


def _fake_package(root):
    """src/feeder with a stage module that imports one helper at module level and one inside a
    function, and a helper that imports the core."""
    pkg = root / "feeder"
    (pkg / "stage").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "errors.py").write_text("class FeederError(Exception): ...\n")
    (pkg / "stage" / "__init__.py").write_text("")
    (pkg / "stage" / "a.py").write_text("from feeder.stage import b\n\ndef f():\n    from feeder.stage.c import g\n")
    (pkg / "stage" / "b.py").write_text("import numpy\nfrom feeder.errors import FeederError\n")
    (pkg / "stage" / "c.py").write_text("def g(): ...\n")
    (pkg / "stage" / "unused.py").write_text("")
    return root


def test_code_modules_follow_function_local_imports_and_packages(tmp_path):
    root = _fake_package(tmp_path)
    assert feeder_imports("feeder.stage.a", root) == {"feeder.stage.b", "feeder.stage.c"}
    assert code_modules("feeder.stage.a", root=root) == [
        "feeder",
        "feeder.errors",
        "feeder.stage",
        "feeder.stage.a",
        "feeder.stage.b",
        "feeder.stage.c",
    ]
    assert module_file("feeder.stage", root) == f"{root.as_posix()}/feeder/stage/__init__.py"
    assert module_file("feeder.stage.nothing", root) is None


def test_feeder_imports_reads_a_module_again_once_it_changes(tmp_path):
    """Each file is parsed once per version (a Snakefile parse asks ~1,800 times), so the cache
    must see an edit, and a module that appears later, in a long-lived process."""
    root = _fake_package(tmp_path)
    a = root / "feeder" / "stage" / "a.py"
    assert feeder_imports("feeder.stage.a", root) == {"feeder.stage.b", "feeder.stage.c"}
    before = a.stat().st_mtime_ns
    a.write_text("from feeder.stage import b, d\nimport feeder.errors\n")
    os.utime(a, ns=(before + 10**9, before + 10**9))  # a new version even on a coarse clock
    assert feeder_imports("feeder.stage.a", root) == {"feeder.stage.b", "feeder.stage", "feeder.errors"}
    (root / "feeder" / "stage" / "d.py").write_text("")  # ``from feeder.stage import d`` is now a module
    assert feeder_imports("feeder.stage.a", root) == {"feeder.stage.b", "feeder.stage.d", "feeder.errors"}


def test_code_inputs_of_a_command_include_its_dispatcher_and_figure_module():
    files = code_inputs("figure", "fig12_test_predictions")
    assert {
        "src/feeder/cli.py",
        "src/feeder/figures/__init__.py",
        "src/feeder/figures/fig12_test_predictions.py",
        "src/feeder/figures/_cdf_predictions.py",
        "src/feeder/figures/style.py",
    } <= set(files)
    sim = code_inputs("simulate")
    assert "src/feeder/sim/drops.py" in sim and "src/feeder/parts/geometry.py" in sim
    assert not any("learn" in f for f in sim)  # a training edit never reruns a simulation


def test_code_inputs_refuse_an_unknown_command():
    with pytest.raises(FeederError, match="no feeder command"):
        code_inputs("no-such-command")


def test_cli_options_join_lists_with_commas():
    assert cli_options({"chosen": 15, "ids": [1, 2], "name": "faithful"}) == "--chosen 15 --ids 1,2 --name faithful"
    assert cli_options({}) == ""


def test_interpreter_dir_goes_first_on_path():
    env = {"PATH": "/usr/bin:/bin"}
    put_interpreter_on_path(env)
    put_interpreter_on_path(env)  # idempotent
    assert env["PATH"].split(os.pathsep) == [os.path.dirname(sys.executable), "/usr/bin", "/bin"]


def test_hydra_settings_come_from_the_run_directory_when_it_has_them(tmp_path):
    from pathlib import Path

    from feeder.config import hydra_config_dir

    repo = Path(hydra_config_dir(tmp_path))  # falls back to the repository's config/hydra
    assert repo.parts[-2:] == ("config", "hydra")
    assert all((repo / name).is_file() for name in ("train.yaml", "vae.yaml", "delta.yaml", "model/m3.yaml"))
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "train.yaml").write_text("seed: 0\n")  # the old place is not read
    assert Path(hydra_config_dir(tmp_path)) == repo
    (tmp_path / "config" / "hydra").mkdir()
    (tmp_path / "config" / "hydra" / "train.yaml").write_text("seed: 0\n")
    assert hydra_config_dir(tmp_path) == str((tmp_path / "config" / "hydra").resolve())


def test_compose_config_reads_the_run_directory_and_errors_are_one_line(tmp_path, monkeypatch):
    from feeder.config import compose_config

    (tmp_path / "config" / "hydra").mkdir(parents=True)
    (tmp_path / "config" / "hydra" / "vae.yaml").write_text("seed: 3\ntrain:\n  epochs: 2\n")
    monkeypatch.chdir(tmp_path)
    assert compose_config("vae", ["train.epochs=5"]).train.epochs == 5
    assert compose_config("vae").seed == 3
    for name, overrides in (("vae", ["train.nonexistent=1"]), ("vae", ["=="]), ("missing", [])):
        with pytest.raises(FeederError) as err:
            compose_config(name, overrides)
        assert "\n" not in str(err.value) and name in str(err.value)


def test_resolved_yaml_drops_keys_and_resolves_interpolations(tmp_path):
    from feeder.config import resolved_yaml

    (tmp_path / "t.yaml").write_text("a: 1\nb: ${a}\npaths:\n  out: x\n")
    assert resolved_yaml("t", ["a=2"], drop=("paths",), config_dir=tmp_path) == "a: 2\nb: 2\n"


class _Scheduler:
    def __init__(self, limiter):
        self.job_rate_limiter = limiter


_LIMITER = object()  # a stand-in for Snakemake's job rate limiter


class _Workflow:
    def __init__(self, local, limiter=_LIMITER, scheduler=True):
        self.local_exec = local
        if scheduler:
            self.scheduler = _Scheduler(limiter)


def test_job_rate_limit_is_dropped_only_for_local_runs():
    from feeder.workflow import drop_local_job_rate_limit

    said = []
    local = _Workflow(local=True)
    assert drop_local_job_rate_limit(local, log=said.append) is True
    assert local.scheduler.job_rate_limiter is None and len(said) == 1
    assert drop_local_job_rate_limit(local, log=said.append) is False  # already off: no second message
    remote = _Workflow(local=False)
    limiter = remote.scheduler.job_rate_limiter
    assert drop_local_job_rate_limit(remote, log=said.append) is False
    assert remote.scheduler.job_rate_limiter is limiter  # cluster runs keep the limit
    assert drop_local_job_rate_limit(_Workflow(local=True, scheduler=False), log=said.append) is False
    assert len(said) == 1


def test_a_run_that_simulates_says_how_many_and_for_what():
    from types import SimpleNamespace

    from feeder.workflow import simulations_notice

    def jobs(*rules):
        return [SimpleNamespace(rule=SimpleNamespace(name=r)) for r in rules]

    assert simulations_notice(jobs("draw_fig9_example_pmfs", "bench_designs")) is None
    said = simulations_notice(jobs("simulate", "simulate", "datasets_build"), {"results/tables/table4.csv"})
    assert "simulates 2 configurations for results/tables/table4.csv" in said
    assert "make fresh" in said and "never committed" in said
    assert "for" not in simulations_notice(jobs("simulate")).split("configurations")[1][:5]


def test_config_overlays_merge_nested_sections_and_replace_lists(tmp_path):
    import pytest

    from feeder.config import load_study_config, overlay_config
    from feeder.errors import FeederError

    assert overlay_config({"a": {"b": 1, "c": [1, 2]}, "d": 0}, {"a": {"c": [3]}, "e": 5}) == {
        "a": {"b": 1, "c": [3]},
        "d": 0,
        "e": 5,
    }
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "config.yaml").write_text("sim:\n  drops: 1000\n  preset: fast\n")
    (tmp_path / "over.yaml").write_text("sim:\n  drops: 50\n")
    assert load_study_config("over.yaml", root=tmp_path) == {"sim": {"drops": 50, "preset": "fast"}}
    with pytest.raises(FeederError, match="missing.yaml"):
        load_study_config("missing.yaml", root=tmp_path)
