import pytest

from feeder.errors import FeederError
from feeder.lane.fences import Fence, config_id, parse_config_id, parse_location, parse_token


def test_round_trip_tokens_and_specs():
    for spec in ["none", "straight:30", "curved:0", "curved:90", "straight:22.5"]:
        fence = parse_location(spec)
        assert fence.spec == spec
        assert parse_token(fence.token) == fence
    cid = config_id(parse_location("straight:30"), parse_location("none"))
    assert cid == "straight30_none"
    assert parse_config_id(cid) == (Fence("straight", 30.0), Fence("none"))


@pytest.mark.parametrize(
    "bad",
    [
        "straight:0",
        "straight:90",
        "curved:-1",
        "curved:90.5",
        "wavy:10",
        "straight",
        "straight:abc",
        "straight:nan",
        "none:5",
    ],
)
def test_bad_locations_are_one_line_errors(bad):
    with pytest.raises(FeederError) as err:
        parse_location(bad)
    assert "\n" not in str(err.value)


def test_bad_tokens():
    for bad in ["straight", "none30", "curved95", "x_y_z"]:
        with pytest.raises(FeederError):
            parse_config_id(bad) if "_" in bad else parse_token(bad)
