"""The ARCS link's settings: AUBO's documented ranges refused outside, the password from a file
or the environment only, and never in a recording's config."""

import json
from pathlib import Path

import pytest

from hilrig.cli.robot_options import real_endpoints
from hilrig.errors import HilrigError, ParameterError
from hilrig.rig.arcs.settings import PASSWORD_ENV, ArcsSettings, password_from
from hilrig.rig.config_file import read_rig_file
from hilrig.rig.session_config import SessionConfig


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"servo_rate_hz": 501.0}, "servo rate 501.0 Hz: must be within 1..500 Hz"),
        ({"servo_rate_hz": 0.5}, "servo rate 0.5 Hz: must be within 1..500 Hz"),
        ({"lookahead_s": 0.01}, "servo look-ahead 0.01 s: must be within 0.03..0.2 s"),
        ({"gain": 2500.0}, "servo gain 2500.0: must be within 100..2000"),
        ({"gain": float("nan")}, "servo gain nan: must be within 100..2000"),
        ({"rtde_rate_hz": 1000.0}, "RTDE rate 1000.0 Hz: must be within 1..500 Hz"),
        ({"rpc_port": 0}, "rpc port 0: must be within 1..65535"),
    ],
)
def test_values_outside_aubo_s_ranges_are_refused(change: dict[str, float], message: str) -> None:
    with pytest.raises(ParameterError) as err:
        ArcsSettings(**change)  # type: ignore[arg-type]
    assert str(err.value).startswith(message)


def test_the_password_is_read_from_a_file_or_the_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    secret = tmp_path / "pw"
    secret.write_text("s3cret\nignored\n")
    assert password_from(secret) == "s3cret"
    monkeypatch.setenv(PASSWORD_ENV, "from-env")
    assert password_from(None) == "from-env"
    monkeypatch.delenv(PASSWORD_ENV)
    with pytest.raises(ParameterError, match=f"give --robot-password-file or set {PASSWORD_ENV}"):
        password_from(None)
    with pytest.raises(ParameterError, match=r"password file .*missing: No such file"):
        password_from(tmp_path / "missing")


def test_the_password_never_reaches_the_recording_s_config(tmp_path: Path) -> None:
    settings = ArcsSettings(password="s3cret-pw")
    assert "s3cret-pw" not in repr(settings)
    config = SessionConfig(out=tmp_path / "s.mcap", subject_id="S001", arcs=settings)
    record = json.loads(config.as_json())
    assert record["robot_link"] == "arcs"
    assert record["arcs"]["servo_rate_hz"] == 200.0
    assert "password" not in record["arcs"]
    assert "s3cret-pw" not in config.as_json()


def test_a_config_file_names_the_controller_and_refuses_a_password(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(
        '[endpoints]\nft_wrist_port = "/dev/ttyUSB0"\n'
        '[robot]\nhost = "192.168.1.10"\nrtde_port = 30011\n'
    )
    endpoints = read_rig_file(path).endpoints
    assert endpoints is not None
    assert endpoints.aubo_rpc == ("192.168.1.10", 30004)
    assert endpoints.aubo_rtde == ("192.168.1.10", 30011)
    assert endpoints.modbus == ("", 0)
    path.write_text(
        '[endpoints]\nft_wrist_port = "/dev/ttyUSB0"\n[robot]\nhost = "h"\npassword = "x"\n'
    )
    with pytest.raises(HilrigError, match=r"\[robot\] password: a password has no place in a"):
        read_rig_file(path)
    path.write_text('[endpoints]\nft_wrist_port = "/dev/ttyUSB0"\n')
    endpoints = read_rig_file(path).endpoints
    assert endpoints is not None and endpoints.aubo_rpc == ("", 0)  # --robot HOST names it
    assert real_endpoints(read_rig_file(path), "10.0.0.9").aubo_rtde == ("10.0.0.9", 30010)
