"""``--config`` files (hilrig.rig.config_file): endpoints, trajectory, what is refused."""

import re
from pathlib import Path

import pytest

from hilrig.emulator.rig import RigEndpoints
from hilrig.errors import HilrigError, OutputError
from hilrig.rig.config_file import read_rig_file, session_path


def test_endpoints_and_trajectory(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(
        '[endpoints]\nft_wrist_port = "/dev/ttyUSB0"\nrobot_state = "10.0.0.2:8002"\n'
        'modbus = "10.0.0.2:502"\n[trajectory]\nname = "circle"\nradius_m = 0.05\n'
    )
    config = read_rig_file(path)
    assert config.endpoints == RigEndpoints("/dev/ttyUSB0", ("10.0.0.2", 8002), ("10.0.0.2", 502))
    assert (config.trajectory, config.trajectory_options) == ("circle", {"radius_m": 0.05})


def test_either_table_may_be_left_out(tmp_path: Path) -> None:
    path = tmp_path / "empty.toml"
    path.write_text("")
    config = read_rig_file(path)
    assert (config.endpoints, config.trajectory, config.trajectory_options) == (None, None, {})


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[endpoints]\nmodbus = "host"\n', "no valid [endpoints] table"),
        ("[endpoints\n", "cannot read the config"),
    ],
)
def test_a_bad_file_is_named(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(HilrigError, match=rf"^{path}: {re.escape(message)}"):
        read_rig_file(path)


def test_session_path_checks_but_makes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    given = tmp_path / "new" / "s.mcap"
    assert session_path(given, "S001") == given and not given.parent.exists()
    monkeypatch.chdir(tmp_path)
    default = session_path(None, "S001-replay")
    assert default.parent == Path("recordings") and not default.parent.exists()
    assert default.name.startswith("S001-replay-") and default.suffix == ".mcap"
    (tmp_path / "taken.mcap").write_bytes(b"")
    with pytest.raises(OutputError, match=r"taken\.mcap: already exists; refusing to overwrite"):
        session_path(tmp_path / "taken.mcap", "S001")


def test_default_paths_made_in_one_second_differ(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    names = [session_path(None, "S001").name for _ in range(50)]
    assert len(set(names)) == 50
    assert all(re.fullmatch(r"S001-\d{8}-\d{6}-[0-9a-z]{5}\.mcap", n) for n in names), names


def test_a_trajectory_table_that_does_not_build_is_named_with_the_file(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text('[trajectory]\nname = "waypoints"\npoints = [[1.0, 0.0, 0.0]]\n')
    with pytest.raises(HilrigError, match=rf"^{path}: \[trajectory\] trajectory option points"):
        read_rig_file(path)
