"""The light names the command signatures use are the library's, and the help shows them."""

import pytest
import typer
from typer.testing import CliRunner

from hilrig.cli import app, options
from hilrig.cli.rig import rig_app
from hilrig.cli.study import study_app
from hilrig.control import Law
from hilrig.rig import RigKind, SessionConfig
from hilrig.viz import DEFAULT_MAX_POINTS, DEFAULT_MAX_POSES
from hilrig.viz.sinks import GRPC_PORT, WEB_PORT
from hilrig.world.scenarios import SCENARIOS, settings_help


def test_the_mirrors_are_the_library_names() -> None:
    assert [m.value for m in options.LawOption] == [m.value for m in Law]
    assert all(m.law() is Law(m.value) for m in options.LawOption)
    assert tuple(sorted(SCENARIOS)) == options.SCENARIO_NAMES
    assert settings_help() == options.SCENARIO_SETTINGS_HELP
    assert (options.GRPC_PORT, options.WEB_PORT) == (GRPC_PORT, WEB_PORT)
    assert (options.DEFAULT_MAX_POINTS, options.DEFAULT_MAX_POSES) == (
        DEFAULT_MAX_POINTS,
        DEFAULT_MAX_POSES,
    )
    assert SessionConfig.__dataclass_fields__["rig"].type in ("RigKind", RigKind)


@pytest.mark.parametrize(
    ("command", "shown"),
    [
        (
            ["record"],
            [
                "--controller",
                "<fixed|variable-stiffness|adaptive>",
                "[default: adaptive]",
                "--rig",
                "<emulated|aubo>",
                "[default: emulated]",
                "Volunteer model (emulated rig): hand-contact, none, paper-body,",
                "--subject",
                "[required]",
                "TOML: [endpoints] of a real rig",
                "[trajectory] (name = 'waypoints', points =",
                "[robot] (host, rpc_port, rtde_port of the AUBO controller)",
                "--robot",
                "--robot-link",
                "<arcs|modbus>",
                "[default: arcs]",
                "--robot-password-file",
                "--servo-rate",
                "[default: 200.0]",
                "[scenario] (name =",
                "--scenario-set",
                "KEY=VALUE",
            ],
        ),
        (
            ["replay"],
            [
                "--rig",
                "<emulated|aubo>",
                "NAME.[cartesian.|joint.]PARAM=VALUE",
                "NAME.[GROUP.]PARAM=START:STOP:COUNT",
                "TOML with [endpoints]",
            ],
        ),
        (
            ["view"],
            [
                "NAME.[GROUP.]PARAM=VALUE",
                "[default: 9876]",
                "[default: 9090]",
                "[default: 20000]",
                "[default: 5000]",
            ],
        ),
        (["export"], ["<parquet|csv>", "[default: parquet]"]),
        (["rig", "serve"], ["--scenario", "[default: paper-end-effector]"]),
    ],
)
def test_help_shows_options_choices_and_defaults(command: list[str], shown: list[str]) -> None:
    result = CliRunner().invoke(app, [*command, "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    missing = [text for text in shown if text not in result.output]
    assert missing == []


def test_record_help_lists_every_scenario_s_settings() -> None:
    result = CliRunner().invoke(app, ["record", "--help"], env={"COLUMNS": "200"})
    text = " ".join(line.strip(" │|") for line in result.output.splitlines())
    flat = " ".join(text.split())
    for name in SCENARIOS:
        assert f"{name}:" in flat
    assert "stiffness_n_m=300 (the hand's stiffness, N/m)" in flat
    assert "paper-body: period_s=none" in flat


@pytest.mark.parametrize(
    ("group", "typer_app"), [([], app), (["rig"], rig_app), (["study"], study_app)]
)
def test_command_lists_show_each_first_paragraph_as_one_line(
    group: list[str], typer_app: typer.Typer
) -> None:
    wide = CliRunner().invoke(app, [*group, "--help"], env={"COLUMNS": "400"})
    assert wide.exit_code == 0, wide.output
    assert typer_app.registered_commands
    for command in typer_app.registered_commands:
        assert command.callback is not None and command.callback.__doc__ is not None
        first = " ".join(command.callback.__doc__.split("\n\n")[0].split())
        assert first in wide.output, (command.callback.__name__, first)
