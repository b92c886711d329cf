"""The loop's thread on one CPU (``LoopConfig.cpu``, ``hilrig record --cpu``): only that thread
moves, only while the loop runs, and a CPU it may not run on is refused in one line."""

import os
import threading
import time
from pathlib import Path

import pytest

from hilrig.errors import HilrigError
from hilrig.rig import ControlLoop, LoopConfig, RecorderProcess, SessionConfig, record_session
from hilrig.rig.rig_process import RigProcess
from hilrig.timing import check_cpu, on_cpu

ALLOWED = frozenset(os.sched_getaffinity(0))
RUNS_ON = ", ".join(str(cpu) for cpu in sorted(ALLOWED))
needs_two = pytest.mark.skipif(len(ALLOWED) < 2, reason="pinning shows only with 2 CPUs or more")


@pytest.mark.parametrize("cpu", sorted(ALLOWED))
def test_on_cpu_moves_this_thread_alone_and_puts_it_back(cpu: int) -> None:
    seen: list[set[int]] = []
    inside, done = threading.Event(), threading.Event()

    def other() -> None:
        inside.wait(60)
        seen.append(os.sched_getaffinity(0))
        done.set()

    thread = threading.Thread(target=other)
    thread.start()
    with on_cpu(cpu):
        assert os.sched_getaffinity(0) == {cpu}
        inside.set()
        done.wait(60)
    thread.join()
    assert seen == [set(ALLOWED)]  # a thread already running keeps its CPUs
    assert os.sched_getaffinity(0) == ALLOWED


def test_none_leaves_the_thread_where_it_is() -> None:
    with on_cpu(None):
        assert os.sched_getaffinity(0) == ALLOWED


@pytest.mark.parametrize("cpu", [4096, 1 << 20])
def test_a_cpu_the_thread_may_not_run_on_is_one_line(cpu: int) -> None:
    with pytest.raises(HilrigError) as caught:
        check_cpu(cpu)
    assert str(caught.value) == (
        f"cpu {cpu}: the loop's thread may not run there (Invalid argument); it may run on "
        f"{RUNS_ON}"
    )
    assert os.sched_getaffinity(0) == ALLOWED


@pytest.mark.parametrize("cpu", [-1, 1.0, True])
def test_a_cpu_that_is_no_number_is_refused(cpu: object) -> None:
    with pytest.raises(HilrigError, match=rf"^cpu {cpu}: must be a CPU's number, 0 or more$"):
        LoopConfig(cpu=cpu)  # type: ignore[arg-type]


@needs_two
def test_a_session_runs_its_loop_on_the_cpu_given_and_nothing_else(tmp_path: Path) -> None:
    cpu = max(ALLOWED)
    loop_tid = threading.get_native_id()
    rigs: list[RigProcess] = []
    recorders: list[RecorderProcess] = []
    seen: dict[str, set[frozenset[int]]] = {"loop": set(), "rig": set(), "recorder": set()}
    ended = threading.Event()

    def watch() -> None:  # samples each one's CPUs until the session's processes are gone
        pids = {"loop": loop_tid, "rig": rigs[0].pid, "recorder": recorders[0].pid}
        while not ended.is_set():
            for name, pid in pids.items():
                assert pid is not None
                try:
                    seen[name].add(frozenset(os.sched_getaffinity(pid)))
                except ProcessLookupError:  # the session is ending
                    return
            time.sleep(0.005)

    def on_start(loop: ControlLoop) -> None:
        threading.Thread(target=watch, daemon=True).start()

    config = SessionConfig(
        out=tmp_path / "s.mcap",
        subject_id="S001",
        scenario="hand-contact",
        duration_s=2.0,
        loop=LoopConfig(cpu=cpu),
    )
    try:
        result = record_session(
            config, on_start=on_start, rig_ready=rigs.append, recorder_ready=recorders.append
        )
    finally:
        ended.set()
    assert result.summary.ticks > 0 and result.drops == 0
    assert frozenset({cpu}) in seen["loop"]  # while it ticked
    assert seen["loop"] <= {ALLOWED, frozenset({cpu})}
    assert seen["rig"] == seen["recorder"] == {ALLOWED}  # the processes stay where they were
    assert os.sched_getaffinity(0) == ALLOWED  # and the thread is put back
    assert f'"cpu": {cpu}' in config.as_json()  # the recording says where its loop ran
