import numpy as np
import pytest

from feeder import io


def test_atomic_write_replaces_only_on_success(tmp_path):
    target = tmp_path / "sub" / "out.txt"
    io.write_text(target, "first")
    with pytest.raises(RuntimeError):
        with io.atomic_path(target) as tmp:
            tmp.write_text("half-writ")
            raise RuntimeError("crash mid-write")
    assert target.read_text() == "first"
    assert [p.name for p in target.parent.iterdir()] == ["out.txt"]  # no temp file left behind


def test_npz_and_json_round_trip(tmp_path):
    io.write_npz(tmp_path / "a.npz", x=np.arange(3.0), s=np.array(["ok", "jammed"]))
    with np.load(tmp_path / "a.npz") as data:
        assert data["x"].tolist() == [0.0, 1.0, 2.0]
        assert data["s"].tolist() == ["ok", "jammed"]
    io.write_json(tmp_path / "b.json", {"b": 1, "a": [1, 2]})
    assert (tmp_path / "b.json").read_text().startswith('{\n  "a"')


def test_parse_settings_requires_an_object_with_the_named_sections():
    from feeder.config import parse_settings
    from feeder.errors import FeederError

    assert parse_settings('{"sim": {"drops": 3}, "labels": {}}', "sim") == {"sim": {"drops": 3}, "labels": {}}
    for text, needle in (("{", "not valid JSON"), ("[1, 2]", "JSON object"), ('{"sim": {}}', "labels")):
        with pytest.raises(FeederError, match=needle):
            parse_settings(text, "sim", "labels")


def test_results_get_the_usual_file_mode_not_a_private_one(tmp_path):
    import os

    old = os.umask(0o022)
    try:
        io.write_text(tmp_path / "r.txt", "x")
    finally:
        os.umask(old)
    assert (tmp_path / "r.txt").stat().st_mode & 0o777 == 0o644
