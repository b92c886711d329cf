"""What ``hilrig replay --closed-loop`` prints after the offsets: the fitted world, the
reproduction check and, per run and collision, the force the person would have met."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from hilrig.replay.job import Replayed

EXTRAPOLATED_S = 0.05  # predicted contact this long past the recorded one's end is flagged
UNITS = {"spring-damper": ("N/m", "N*s/m"), "hunt-crossley": ("N/m^1.5", "s/m")}


def closed_summary(replayed: Replayed) -> list[str]:
    """The closed-loop record of ``replayed``'s table, for people."""
    from hilrig.replay.results import INPUT_KEY

    record: dict[str, Any] = replayed.table.attrs[INPUT_KEY]["closed_loop"]
    r = record["response"]
    loop = r["recorded_sensor_to_command_us"]
    measured = (
        ""
        if loop is None
        else f"; the loop's sensor to command p50 {loop[0]:.0f} us, p99 {loop[1]:.0f} us"
    )
    lines = [
        f"closed loop: the arm's response: servo bandwidth {r['bandwidth_rad_s']:.1f} rad/s, "
        f"delay {1000 * r['delay_s']:.1f} ms ({r['source']}; RMS joint error "
        f"{1000 * r['rms_rad']:.3f} mrad){measured}"
    ]
    if record["recorded_link_holds"]:
        lines.append(
            f"the live loop held {record['recorded_link_holds']} ticks for a stale link or a "
            "failed command: every run holds on them too"
        )
    collisions = record["collisions"]
    if not collisions:
        lines.append("no collision in the recording: every run met the recorded force")
    for c in collisions:
        lines.append(f"{c['name']} (to {c['t_s'][1]:.2f} s): {_model(c)}")
        lines.append(
            f"  fit R^2 {c['r2']:.3f}, RMS {c['rms_n']:.2f} N; the recorded controller "
            f"re-simulated: peak {c['recorded_peak_n']:.2f} -> {c['reproduced_peak_n']:.2f} N "
            f"({c['reproduction_peak_error_pct']:.1f} %), impulse "
            f"{c['reproduction_impulse_error_pct']:.1f} % off"
        )
    for index, (name, rows) in enumerate(record["predicted"].items(), 1):  # 0: the recorded
        parts = []
        for number, (c, got) in enumerate(zip(collisions, rows, strict=True), 1):
            part = (
                f"#{number} peak {got['peak_n']:.2f} N (recorded {c['recorded_peak_n']:.2f}), "
                f"impulse {got['impulse_n_s']:.2f} N*s (recorded {c['recorded_impulse_n_s']:.2f})"
            )
            if got["contact_beyond_s"] > EXTRAPOLATED_S:
                part += (
                    f", in contact {got['contact_beyond_s']:.2f} s past the recorded contact's "
                    "end (the body's motion there is extrapolated)"
                )
            parts.append(part)
        held, stopped = record["hold_ticks"][index], record["stopped"][index]
        tail = f"; {held} hold ticks" if held else ""
        tail += "; protective stop (the force exceeded its limit)" if stopped else ""
        lines.append(f"predicted for {name}: " + ("; ".join(parts) or "no collision") + tail)
    return lines


def _model(c: dict[str, Any]) -> str:
    direction = ", ".join(f"{v:.2f}" for v in c["direction_in_base"])
    if c["mechanics"] == "force-source":
        return (
            f"a force source along ({direction}) (the robot's motion improves the fit of a "
            f"body only {c['motion_gain']:.2f} times): replayed as recorded"
        )
    k_unit, c_unit = UNITS[c["mechanics"]]
    point = ", ".join(f"{v:.3f}" for v in c["contact_point_in_sensor_m"])
    surface = c["surface"]
    return (
        f"{c['mechanics']} along ({direction}), k {c['stiffness']:.4g} {k_unit}, "
        f"c {c['damping']:.3g} {c_unit}, at ({point}) m in the sensor frame; the body came in "
        f"at {surface['v_in_m_s']:.3f} m/s to {1000 * surface['h_max_m']:.1f} mm, held "
        f"{surface['t_back_s'] - surface['t_full_s']:.2f} s, left at "
        f"{surface['v_out_m_s']:.3f} m/s"
    )
