"""The workflow validates its config against workflow/schemas/config.schema.yaml at start."""

import copy
from pathlib import Path

import pytest
import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate
from workflow_helpers import merged_config

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = str(ROOT / "workflow" / "schemas" / "config.schema.yaml")


def _load(name):
    return yaml.safe_load((ROOT / "config" / name).read_text())


def _merged_smoke():
    return merged_config(ROOT, "config/smoke.yaml")


@pytest.mark.parametrize("config", [_load("config.yaml"), _merged_smoke()], ids=["default", "smoke"])
def test_shipped_configs_are_valid(config):
    validate(copy.deepcopy(config), schema=SCHEMA)


OVERLAYS = sorted(p.name for p in (ROOT / "config").glob("*.yaml") if p.name != "config.yaml")


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_every_committed_overlay_merges_into_a_valid_config(overlay):
    """`snakemake --configfile config/<overlay>` validates the merged config at start: every overlay the
    repository ships must pass, and must write under its own results folder."""
    assert len(OVERLAYS) >= 10  # the glob found the folder
    merged = merged_config(ROOT, f"config/{overlay}")
    validate(copy.deepcopy(merged), schema=SCHEMA)
    assert merged["results"] != _load("config.yaml")["results"], overlay


def test_the_hull_overlay_changes_only_the_curved_fences_build():
    """config/hull.yaml (issue #39's seam-free candidate) differs from the default in the curved fences'
    build and chord count, its results folder and its export folder, nothing else."""
    overlay = _load("hull.yaml")
    assert overlay["scene"] == {"fences": {"curved": {"build": "hull", "segments": 64}}}
    assert set(overlay) == {"results", "scene", "models"}
    assert overlay["results"] == "results/hull" and overlay["models"] == {"export_dir": "results/hull/shipped"}


def test_a_square_fence_tip_is_a_valid_setting_and_the_default_is_round():
    default = _load("config.yaml")
    assert default["scene"]["fences"]["tip"] == "round"  # issue #39's re-baseline
    validate(_set(copy.deepcopy(default), "scene.fences.tip", "square"), schema=SCHEMA)
    with pytest.raises(WorkflowError):
        validate(_set(copy.deepcopy(default), "scene.fences.tip", "pointed"), schema=SCHEMA)


def _set(config, dotted, value):
    *path, last = dotted.split(".")
    node = config
    for key in path:
        node = node[key]
    if value is _DELETE:
        del node[last]
    else:
        node[last] = value
    return config


_DELETE = object()

BAD = [
    ("sim.drops", -5, "drops"),  # out of range
    ("sim.drops", "many", "drops"),  # wrong type
    ("sim.dorps", 10, "dorps"),  # unknown key (typo)
    ("labels.on_bad", "ignore", "on_bad"),  # not in enum
    ("datasets.test_fraction", 1.5, "test_fraction"),
    ("labels.levels_pct", [0, 50], "levels_pct"),
    ("parts.include", ["bad_id"], "include"),
    ("models.regression", ["m9"], "regression"),
    ("bogus_section", {}, "bogus_section"),
    ("sim.preset", _DELETE, "preset"),  # missing required key
    ("scene.fences.tip", "pointy", "tip"),  # not in enum (the key itself is optional)
]


@pytest.mark.parametrize("dotted,value,named", BAD, ids=[b[0] + ":" + repr(b[1])[:12] for b in BAD])
def test_bad_config_stops_with_the_key_named(dotted, value, named):
    config = _set(copy.deepcopy(_load("config.yaml")), dotted, value)
    with pytest.raises(WorkflowError) as err:
        validate(config, schema=SCHEMA)
    assert named in str(err.value)


def test_a_shipped_model_without_its_tables_stops_the_workflow_at_parse_time(tmp_path):
    """models.ship names a model that is not trained with a GroupKFold: one clear error, no job."""
    import subprocess

    from workflow_helpers import SNAKEMAKE

    overlay = tmp_path / "ship.yaml"
    overlay.write_text(yaml.safe_dump({"models": {"ship": ["m3push"], "groupkfold": ["m3"]}}))
    proc = subprocess.run(
        [SNAKEMAKE, "-n", "--configfile", str(overlay)], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode != 0
    assert "models.ship: m3push must also be in models.regression and models.groupkfold" in proc.stderr + proc.stdout


@pytest.mark.parametrize("dotted,value,named", BAD, ids=[b[0] + ":" + repr(b[1])[:12] for b in BAD])
def test_the_workflows_own_check_names_the_setting_in_one_line(dotted, value, named):
    """What common.smk raises instead of Snakemake's message, which quotes the whole schema."""
    from feeder.config import check_study_config
    from feeder.errors import FeederError

    config = _set(copy.deepcopy(_load("config.yaml")), dotted, value)
    with pytest.raises(FeederError) as err:
        check_study_config(config, "config", SCHEMA)
    message = str(err.value)
    assert message.startswith("config: ") and named in message and "\n" not in message and len(message) < 300


def test_an_unknown_sim_preset_is_named_with_the_presets_there_are():
    from feeder.config import check_study_config
    from feeder.errors import FeederError

    config = _set(copy.deepcopy(_load("config.yaml")), "sim.preset", "nosuch")
    validate(copy.deepcopy(config), schema=SCHEMA)  # the schema cannot see it
    with pytest.raises(FeederError, match=r"config: sim.preset: 'nosuch' is not one of sim.presets \(faithful, "):
        check_study_config(config, "config", SCHEMA)


@pytest.mark.parametrize(
    "overlay, message",
    [
        ({"sim": {"dropz": 10}}, "config: sim: Additional properties are not allowed ('dropz' was unexpected)"),
        ({"sim": {"preset": "nosuch"}}, "config: sim.preset: 'nosuch' is not one of sim.presets"),
    ],
)
def test_a_bad_setting_stops_the_workflow_in_a_few_lines(tmp_path, overlay, message):
    import subprocess

    from workflow_helpers import SNAKEMAKE

    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(overlay))
    proc = subprocess.run(
        [SNAKEMAKE, "-n", "--configfile", str(path)], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    said = proc.stderr + proc.stdout
    assert proc.returncode != 0 and message in said
    assert len(said.splitlines()) < 20  # not the schema (thousands of lines)
