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
