import json
import os
import sys

from feeder.workflow import module_files, put_interpreter_on_path, select_settings


def test_select_settings_keeps_nesting_and_only_the_named_keys():
    config = {"sim": {"drops": 50, "min_ok_drops": 20, "presets": {"fast": {}}}, "labels": {"bins": 360}}
    picked = json.loads(select_settings(config, "sim.min_ok_drops", "labels"))
    assert picked == {"sim": {"min_ok_drops": 20}, "labels": {"bins": 360}}
    # the same settings in another order give the same string (a stable rerun trigger)
    assert select_settings(config, "labels", "sim.min_ok_drops") == select_settings(config, "sim.min_ok_drops", "labels")


def test_module_files_include_core_once():
    files = module_files("sim", "io", "scene")
    assert files[:3] == ["src/feeder/__init__.py", "src/feeder/errors.py", "src/feeder/io.py"]
    assert files.count("src/feeder/io.py") == 1 and files[-2:] == ["src/feeder/sim.py", "src/feeder/scene.py"]


def test_interpreter_dir_goes_first_on_path():
    env = {"PATH": "/usr/bin:/bin"}
    put_interpreter_on_path(env)
    put_interpreter_on_path(env)  # idempotent
    assert env["PATH"].split(os.pathsep) == [os.path.dirname(sys.executable), "/usr/bin", "/bin"]


def test_hydra_settings_come_from_the_run_directory_when_it_has_them(tmp_path):
    from pathlib import Path

    from feeder.workflow import hydra_config_dir

    assert Path(hydra_config_dir(tmp_path)).joinpath("train.yaml").is_file()  # falls back to the repo
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "train.yaml").write_text("seed: 0\n")
    assert hydra_config_dir(tmp_path) == str((tmp_path / "config").resolve())


class _Scheduler:
    def __init__(self, limiter):
        self.job_rate_limiter = limiter


class _Workflow:
    def __init__(self, local, limiter=object(), scheduler=True):
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


def test_config_overlays_merge_nested_sections_and_replace_lists(tmp_path):
    import pytest

    from feeder.errors import FeederError
    from feeder.workflow import load_study_config, overlay_config

    assert overlay_config({"a": {"b": 1, "c": [1, 2]}, "d": 0}, {"a": {"c": [3]}, "e": 5}) == {
        "a": {"b": 1, "c": [3]}, "d": 0, "e": 5}
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "config.yaml").write_text("sim:\n  drops: 1000\n  preset: fast\n")
    (tmp_path / "over.yaml").write_text("sim:\n  drops: 50\n")
    assert load_study_config("over.yaml", root=tmp_path) == {"sim": {"drops": 50, "preset": "fast"}}
    with pytest.raises(FeederError, match="missing.yaml"):
        load_study_config("missing.yaml", root=tmp_path)
