import pytest

from feeder.errors import FeederError
from feeder.report import cost_by_stage, read_benchmarks

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def _bench(path, wall, cpu, rss):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + f"{wall}\t0:00:01\t{rss}\t1\t1\t1\t0\t0\t50\t{cpu}\n")


def test_cost_by_stage_sums_per_stage(tmp_path):
    _bench(tmp_path / "simulate" / "a" / "x.tsv", 2.0, 1.5, 100.0)
    _bench(tmp_path / "simulate" / "b" / "y.tsv", 3.0, 2.5, 120.0)
    _bench(tmp_path / "train" / "m3.tsv", 10.0, 19.0, 900.0)
    table = cost_by_stage(read_benchmarks(tmp_path))
    rows = table.set_index("stage")
    assert list(table["stage"]) == ["train", "simulate", "TOTAL"]
    assert rows.loc["simulate", "jobs"] == 2
    assert rows.loc["simulate", "wall_s"] == pytest.approx(5.0)
    assert rows.loc["simulate", "cpu_s"] == pytest.approx(4.0)
    assert rows.loc["simulate", "max_rss_mb"] == pytest.approx(120.0)
    assert rows.loc["TOTAL", "wall_s"] == pytest.approx(15.0)
    assert rows.loc["TOTAL", "jobs"] == 3


def test_broken_benchmark_file_is_named(tmp_path):
    bad = tmp_path / "simulate" / "x.tsv"
    bad.parent.mkdir(parents=True)
    bad.write_text("")
    with pytest.raises(FeederError, match="x.tsv"):
        read_benchmarks(tmp_path)


def test_empty_benchmarks_give_empty_table(tmp_path):
    assert cost_by_stage(read_benchmarks(tmp_path)).empty


def test_the_run_config_is_written_alone_and_read_back_into_the_provenance(tmp_path):
    import hashlib
    import json

    from feeder.report import main

    config_json = json.dumps({"sim": {"drops": 40}}, sort_keys=True, separators=(",", ":"))
    run_config = tmp_path / "run_config.json"
    assert main(["--config-json", config_json, "--config-out", str(run_config)]) == 0
    assert run_config.read_text() == config_json  # the text itself: its hash is the record's
    _bench(tmp_path / "bench" / "simulate" / "x.tsv", 2.0, 1.5, 100.0)
    out, prov = tmp_path / "cost.csv", tmp_path / "provenance.json"
    argv = ["--benchmarks", str(tmp_path / "bench"), "--out-csv", str(out), "--provenance", str(prov)]
    assert main([*argv, "--config-file", str(run_config)]) == 0
    record = json.loads(prov.read_text())
    assert record["config"] == {"sim": {"drops": 40}}
    assert record["config_sha256"] == hashlib.sha256(config_json.encode()).hexdigest()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--config-out", "{tmp}/c.json"], "--config-out writes the config given as --config-json"),
        (["--config-json", "{{", "--config-out", "{tmp}/c.json"], "--config-json: not JSON"),
        (["--config-json", "{{}}", "--config-file", "{tmp}/x.json", "--out-csv", "{tmp}/o.csv"], "not both"),
        (["--config-file", "{tmp}/missing.json", "--out-csv", "{tmp}/o.csv"], "not found"),
        ([], "give --out-csv"),
    ],
)
def test_feeder_cost_bad_arguments_are_one_line_and_write_nothing(tmp_path, capsys, argv, message):
    from feeder.cli import main

    argv = [a.format(tmp=tmp_path) for a in argv]
    assert main(["cost", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not any(tmp_path.iterdir())
