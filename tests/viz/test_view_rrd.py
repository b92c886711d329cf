"""A session and its replays to ``.rrd``, read back with Rerun's reader and checked against the
official MCAP reader (recorded values), the replay engine (replayed values) and pinocchio."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rrd_helpers import Rrd

from hilrig.recording import ControllerSample, SessionInfo, SessionWriter, default_channels
from hilrig.replay import ForceTrace, load_trace, parse_specs, run, write_parquet
from hilrig.robot import RobotModel
from hilrig.viz import ViewError, save_rrd, scene_from_session
from hilrig.viz.log import FORCE_SCALE_M_PER_N
from hilrig.viz.style import RUN_PALETTE

EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"
AXES = ("x", "y", "z", "joint1", "joint2", "joint3", "joint4", "joint5", "joint6")
RUNS = ("recorded", "fixed", "soft")
SPECS = (["fixed", "soft=adaptive"], ["soft.cartesian.a1=5"])


def official(topic: str) -> list[tuple[int, object]]:
    """(log time, decoded message) of ``topic`` with the mcap reader and mcap_ros2 decoder."""
    with EXAMPLE.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(m.log_time, d) for _, _, m, d in reader.iter_decoded_messages(topics=[topic])]


@pytest.fixture(scope="module")
def full(tmp_path_factory: pytest.TempPathFactory) -> Rrd:
    out = tmp_path_factory.mktemp("view") / "full.rrd"
    save_rrd(scene_from_session(EXAMPLE, parse_specs(*SPECS)), out, max_points=0, max_poses=0)
    return Rrd(out)


@pytest.fixture(scope="module")
def thinned(tmp_path_factory: pytest.TempPathFactory) -> Rrd:
    out = tmp_path_factory.mktemp("view") / "thinned.rrd"
    save_rrd(scene_from_session(EXAMPLE, parse_specs(*SPECS)), out, max_points=300, max_poses=50)
    return Rrd(out)


def test_every_entity_of_the_tree_is_there(full: Rrd) -> None:
    expected = {
        "/about",
        "/events",
        "/world",
        "/world/robot/links",
        "/world/robot/joints",
        "/world/force",
        "/world/trajectory/desired/path",
        "/world/trajectory/desired/now",
        "/world/trajectory/actual/path",
        "/world/trajectory/actual/now",
        *(f"/world/trajectory/runs/{r}/{p}" for r in RUNS for p in ("path", "now")),
        *(f"/series/input/{a}" for a in AXES),
        *(f"/series/wrist/{c}" for c in ("fx", "fy", "fz", "mx", "my", "mz")),
        *(f"/series/joints/joint{j}" for j in range(1, 7)),
        *(
            f"/series/{q}/{a}/{r}"
            for q in ("offset", "damping", "stiffness", "zeta")
            for a in AXES
            for r in RUNS
        ),
        *(f"/contact/{g}/{r}" for g in ("end\\ effector", "body") for r in RUNS),
    }
    assert full.entities() - {"/__properties"} == expected


def test_recorded_curves_equal_the_official_readers_values(full: Rrd) -> None:
    state = official("/controller/state")
    t0 = state[0][0]
    times = np.array([(t - t0) / 1e9 for t, _ in state])
    for i, axis in enumerate(AXES):
        for quantity in ("offset", "damping", "stiffness", "zeta"):
            t, v = full.scalars(f"/series/{quantity}/{axis}/recorded")
            np.testing.assert_allclose(t, times, atol=1e-9)
            expected = [getattr(m, quantity)[i] for _, m in state]
            np.testing.assert_array_equal(v, expected)
        t, v = full.scalars(f"/series/input/{axis}")
        np.testing.assert_array_equal(v, [m.force[i] for _, m in state])


def test_replayed_curves_equal_the_replay_engine(full: Rrd) -> None:
    table = run(EXAMPLE, parse_specs(*SPECS))
    for name in ("fixed", "soft"):
        rows = table[table["run"] == name]
        for axis in AXES:
            for quantity in ("offset", "damping", "stiffness", "zeta"):
                t, v = full.scalars(f"/series/{quantity}/{axis}/{name}")
                np.testing.assert_array_equal(v, rows[f"{quantity}_{axis}"].to_numpy())
                np.testing.assert_allclose(t, rows["t_s"].to_numpy(), atol=1e-9)


def test_contact_lanes_change_where_the_recorded_state_changes(full: Rrd) -> None:
    state = official("/controller/state")
    t0 = state[0][0]
    codes = np.array([m.contact_state[0] for _, m in state])
    changes = np.flatnonzero(np.diff(codes, prepend=-1))
    t, names = full.temporal("/contact/end\\ effector/recorded", "StateChange:state")
    np.testing.assert_allclose(t, [(state[n][0] - t0) / 1e9 for n in changes], atol=1e-9)
    labels = {0: "free", 1: "contact", 2: "holding", 3: "recovering"}
    assert [n[0] for n in names] == [labels[int(codes[n])] for n in changes]
    assert "contact" in [n[0] for n in names]  # the example holds a collision


def test_events_are_one_text_line_each(full: Rrd) -> None:
    events = official("/events")
    _, texts = full.temporal("/events", "TextLog:text")
    assert len(texts) == len(events)
    assert texts[1] == ["[controller] collision start: end effector"]
    _, levels = full.temporal("/events", "TextLog:level")
    assert [x[0] for x in levels] == ["INFO", "WARN", "INFO", "INFO"]


def test_robot_and_force_arrow_follow_the_measured_joints(full: Rrd) -> None:
    joints = official("/joint_states")
    state = official("/controller/state")
    t0 = state[0][0]
    joint_t = np.array([(t - t0) / 1e9 for t, _ in joints])
    t, strips = full.temporal("/world/robot/links", "LineStrips3D:strips")
    assert len(t) == len(state)
    model = RobotModel()
    for n in (0, len(t) // 2, len(t) - 1):
        latest = max(int(np.searchsorted(joint_t, t[n], side="right")) - 1, 0)
        q = np.array(joints[latest][1].position)
        np.testing.assert_allclose(strips[n][0], model.link_points(q), atol=1e-6)  # float32
    _, vectors = full.temporal("/world/force", "Arrows3D:vectors")
    _, origins = full.temporal("/world/force", "Arrows3D:origins")
    for n in (0, len(t) // 2):
        force = np.array(state[n][1].force[:3])
        np.testing.assert_allclose(vectors[n][0], force * FORCE_SCALE_M_PER_N, rtol=1e-6)
        np.testing.assert_allclose(origins[n][0], strips[n][0][-1])


def test_run_trajectories_are_desired_plus_offset(full: Rrd) -> None:
    desired = official("/trajectory/desired")
    state = official("/controller/state")
    _, points = full.temporal("/world/trajectory/runs/recorded/now", "Points3D:positions")
    for n in (0, len(state) // 2, len(state) - 1):
        p = desired[n][1].pose.position
        expected = np.array([p.x, p.y, p.z]) + np.array(state[n][1].offset[:3])
        np.testing.assert_allclose(points[n][0], expected, rtol=1e-6)
    path = full.static("/world/trajectory/runs/recorded/path", "LineStrips3D:strips")
    assert len(path[0]) == len(state)


def test_one_colour_per_run_in_every_view(full: Rrd) -> None:
    def rgb(packed: int) -> tuple[int, int, int]:
        return (packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255

    for k, name in enumerate(RUNS):
        colours = {
            rgb(full.static(f"/series/{q}/{a}/{name}", "SeriesLines:colors")[0])
            for q in ("offset", "damping", "stiffness", "zeta")
            for a in AXES
        }
        colours.add(
            rgb(full.static(f"/world/trajectory/runs/{name}/path", "LineStrips3D:colors")[0])
        )
        colours.add(rgb(full.static(f"/world/trajectory/runs/{name}/now", "Points3D:colors")[0]))
        assert colours == {RUN_PALETTE[k]}
    label = full.static("/series/offset/x/soft", "SeriesLines:names")
    assert label == ["soft (adaptive)"]


def test_decimation_keeps_peaks_and_the_budget(full: Rrd, thinned: Rrd) -> None:
    for entity in ("/series/input/x", "/series/offset/x/fixed", "/series/damping/x/soft"):
        t_all, v_all = full.scalars(entity)
        t, v = thinned.scalars(entity)
        assert len(v) <= 300 < len(v_all)
        assert v.max() == v_all.max() and v.min() == v_all.min()
        assert set(np.round(t, 9)) <= set(np.round(t_all, 9))  # samples, not made-up points
    t, _ = thinned.temporal("/world/robot/links", "LineStrips3D:strips")
    assert len(t) == 50
    (note,) = thinned.static("/about", "TextDocument:text")
    assert "Display decimated" in note and "untouched" in note
    assert "no decimation" in full.static("/about", "TextDocument:text")[0]
    minmax = 5  # rerun.components.AggregationPolicy.MinMax: zoomed out, peaks stay visible
    for entity in ("/series/input/x", "/series/offset/x/fixed", "/series/joints/joint1"):
        assert full.static(entity, "SeriesLines:aggregation_policy") == [minmax]


def test_the_layout_holds_every_view(full: Rrd, thinned: Rrd) -> None:
    views = full.views()
    kinds = {(v.kind, v.origin) for v in views}
    assert ("3D", "/world") in kinds
    assert ("TextLog", "/events") in kinds
    assert ("TextDocument", "/about") in kinds
    assert ("StateTimeline", "/contact") in kinds
    for origin in ("/series/input", "/series/wrist", "/series/joints"):
        assert ("TimeSeries", origin) in kinds
    for quantity in ("offset", "damping", "stiffness", "zeta"):
        for axis in AXES:
            assert ("TimeSeries", f"/series/{quantity}/{axis}") in kinds
    assert not any("decimated" in v.name for v in views)
    plots = [v for v in thinned.views() if v.kind == "TimeSeries"]
    assert plots and all("[display decimated" in v.name for v in plots)


def test_the_recording_is_named_by_the_session(full: Rrd) -> None:
    (recording,) = full.recordings
    assert recording.application_id == "hilrig"


def test_a_file_that_is_not_a_session_is_refused(tmp_path: Path) -> None:
    table = tmp_path / "trace.csv"
    table.write_text("t,fx\n0,1\n")
    with pytest.raises(ViewError, match=r"trace\.csv: not a session file \(\.mcap\)$"):
        scene_from_session(table)


def test_duplicate_run_names_are_refused() -> None:
    with pytest.raises(
        ViewError,
        match=r"two runs are named 'recorded' \(runs: recorded, recorded\); name a controller "
        "with NAME=LAW$",
    ):
        scene_from_session(EXAMPLE, parse_specs(["recorded=fixed"]))


def test_stored_replay_results_join_the_view(tmp_path: Path) -> None:
    stored = tmp_path / "results.parquet"
    table = run(EXAMPLE, parse_specs(["a=fixed", "b=variable-stiffness"]))
    write_parquet(table, stored)
    scene = scene_from_session(EXAMPLE, parse_specs(["adaptive"]), [stored])
    assert [r.name for r in scene.runs] == ["recorded", "adaptive", "a", "b"]
    assert scene.runs[3].label == "b (variable-stiffness)"
    for name, curves in (("a", scene.runs[2]), ("b", scene.runs[3])):
        rows = table[table["run"] == name]
        np.testing.assert_array_equal(curves.damping[:, 0], rows["damping_x"].to_numpy())
        np.testing.assert_array_equal(curves.contact[:, 4], rows["contact_joint2"].to_numpy())


def test_results_of_another_input_are_refused(tmp_path: Path) -> None:
    stored = tmp_path / "short.parquet"
    trace = load_trace(EXAMPLE)
    short = ForceTrace(trace.t_s[:100], trace.force[:100], trace.axis_names, "x", trace.dt_s)
    write_parquet(run(short, parse_specs(["fixed"])), stored)
    with pytest.raises(
        ViewError,
        match=rf"^{stored}: not a replay of this session \(100 rows for 1 run\(s\), the session "
        r"has 3499 ticks\)$",
    ):
        scene_from_session(EXAMPLE, (), [stored])
    shifted = tmp_path / "shifted.parquet"
    moved = ForceTrace(trace.t_s + 0.5, trace.force, trace.axis_names, "x", trace.dt_s)
    write_parquet(run(moved, parse_specs(["fixed"])), shifted)
    with pytest.raises(ViewError, match=r"not a replay of this session \(tick 0 at 0\.500000 s"):
        scene_from_session(EXAMPLE, (), [shifted])


def test_a_truncated_session_is_shown_with_what_was_lost(tmp_path: Path) -> None:
    cut = tmp_path / "cut.mcap"
    data = EXAMPLE.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.6)])
    scene = scene_from_session(cut)
    assert scene.notes and all(str(cut) in n for n in scene.notes)
    assert 0 < len(scene.t_s) < 3499
    out = tmp_path / "cut.rrd"
    save_rrd(scene, out)
    (note,) = Rrd(out).static("/about", "TextDocument:text")
    assert "Problems reading the file" in note and scene.notes[0] in note


def test_a_session_with_the_controller_state_only_has_no_robot(tmp_path: Path) -> None:
    path = tmp_path / "state-only.mcap"
    info = SessionInfo("s", "S001", "emulated", "adaptive", 1_767_225_600_000_000_000, 0)
    with SessionWriter(path, info, channels=default_channels()) as writer:
        for i in range(50):
            f = [float(i)] * 9
            writer.write(
                "/controller/state", ControllerSample(i * 1_000_000, f, f, f, f, f, f, f, [0] * 9)
            )
    out = tmp_path / "state-only.rrd"
    save_rrd(scene_from_session(path, parse_specs(["fixed"])), out)
    entities = Rrd(out).entities(static=False)
    assert "/series/offset/x/fixed" in entities
    assert not {e for e in entities if e.startswith("/world")}
    _, values = Rrd(out).scalars("/series/input/joint6")
    np.testing.assert_array_equal(values, np.arange(50.0))


def test_the_body_region_s_limits_are_lines_beside_the_force(full: Rrd, tmp_path: Path) -> None:
    assert not {e for e in full.entities() if "limit" in e}  # the example names no region
    scene = scene_from_session(EXAMPLE, parse_specs(["fixed"]))
    assert scene.session is not None
    chest = replace(scene, session=replace(scene.session, body_region="chest"))
    out = tmp_path / "chest.rrd"
    save_rrd(chest, out, max_points=0, max_poses=0)
    rrd = Rrd(out)
    for phase, limit in (("transient", 280.0), ("quasi_static", 140.0)):
        t, values = rrd.scalars(f"/series/input/limit_{phase}")
        np.testing.assert_array_equal(values, [limit, limit])
        assert (t[0], t[-1]) == pytest.approx((scene.t_s[0], scene.t_s[-1]), abs=1e-9)
    _, norm = rrd.scalars("/series/input/norm")
    np.testing.assert_allclose(norm, np.linalg.norm(scene.force[:, :3], axis=1), rtol=1e-6)
    face = replace(scene, session=replace(scene.session, body_region="face"))
    save_rrd(face, tmp_path / "face.rrd", max_points=0, max_poses=0)
    assert "/series/input/limit_transient" not in Rrd(tmp_path / "face.rrd").entities()
