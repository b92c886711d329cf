"""``--config`` files (hilrig.rig.config_file): endpoints, trajectory, what is refused."""

import re
from pathlib import Path

import pytest

from hilrig.emulator.rig import RigEndpoints
from hilrig.errors import HilrigError
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


def test_session_path_makes_its_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    given = tmp_path / "new" / "s.mcap"
    assert session_path(given, "S001") == given and given.parent.is_dir()
    monkeypatch.chdir(tmp_path)
    default = session_path(None, "S001-replay")
    assert default.parent == Path("recordings") and default.parent.is_dir()
    assert default.name.startswith("S001-replay-") and default.suffix == ".mcap"
