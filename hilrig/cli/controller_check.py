"""``hilrig doctor --robot HOST``: the AUBO controller's part of the report."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console

MARK_OK, MARK_WARN = "[green]ok  [/]", "[bold yellow]warn[/]"


def check_robot(
    console: Console,
    host: str,
    ports: tuple[int, int],
    user: str,
    password_file: Path | None,
    rtde_rate_hz: float,
    *,
    quiet: bool,
) -> dict[str, object]:
    """Check the controller, print what was found (unless ``quiet``) and return it as a
    record (with ``problem``: "" when a session may start)."""
    from rich.markup import escape

    from hilrig.rig.arcs.check import SUPPORTED_INTERFACE, check_controller
    from hilrig.rig.arcs.settings import ArcsSettings, password_from

    settings = ArcsSettings(
        host=host,
        rpc_port=ports[0],
        rtde_port=ports[1],
        user=user,
        password=password_from(password_file),
        rtde_rate_hz=rtde_rate_hz,
    )
    if not quiet:
        console.print(f"[bold]AUBO controller[/] {escape(settings.where())}")
    found = check_controller(settings)
    record = {**asdict(found), "problem": found.problem}
    if quiet:
        return record
    if found.error:
        console.print(f"  {MARK_WARN}  link: {escape(found.error)}")
        return record
    version_ok = found.interface_version == SUPPORTED_INTERFACE
    observed = f" (the pinned client was observed with {SUPPORTED_INTERFACE})"
    rate_ok = found.rtde_achieved_hz >= 0.9 * found.rtde_rate_hz
    lines = (
        (True, f"reachable, login as {escape(user)} accepted, robot {escape(found.robot)}"),
        (
            version_ok,
            f"interface version {found.interface_version}" + ("" if version_ok else observed),
        ),
        (found.robot_mode == 8, f"robot mode: {found.robot_mode_name}"),
        (found.safety_mode == 1, f"safety mode: {found.safety_mode_name}"),
        (
            rate_ok,
            f"RTDE joint states: {found.rtde_achieved_hz:.1f} Hz of {found.rtde_rate_hz:g} Hz "
            f"asked ({found.rtde_samples} samples in {found.seconds:g} s)",
        ),
    )
    for ok, text in lines:
        console.print(f"  {MARK_OK if ok else MARK_WARN}  {text}")
    if found.problem:
        console.print(f"  a session cannot start: {escape(found.problem)}")
    return record
