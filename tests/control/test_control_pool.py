"""``simulate``'s output pool: a dropped result's block serves the next call, a live one never.

The oracle for every value is ``run_into`` writing into the test's own ``np.empty`` arrays,
which no pool touches; block identity is read from the arrays' data pointers.
"""

import multiprocessing
import threading
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.control import (
    OUTPUTS,
    NonFiniteForceError,
    SimResult,
    combine,
    make,
    pool,
    preset,
    release_memory,
    simulate,
)

PARAMS = combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6))
DT = 0.001
AXES = 9
FIELDS = (*OUTPUTS, "contact")


def ticks_for(nbytes: int) -> int:
    """Ticks whose outputs and contact codes (33 bytes per axis-tick) take at least nbytes."""
    return -(-nbytes // (AXES * (8 * len(OUTPUTS) + 1)))


BIG = ticks_for(pool.MIN_BYTES)  # the smallest trace whose block is pooled


def trace(ticks: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    force = rng.normal(scale=0.05, size=(ticks, AXES))
    force[ticks // 4 : ticks // 2, rng.integers(AXES)] += rng.uniform(2.0, 8.0)
    return force


def oracle(force: np.ndarray) -> dict[str, np.ndarray]:
    out = np.empty((len(OUTPUTS), *force.shape))
    contact = np.empty(force.shape, dtype=np.int8)
    make("adaptive", PARAMS, dt=DT).run_into(force, out, contact)
    return {**dict(zip(OUTPUTS, out, strict=True)), "contact": contact}


def assert_equals(result: SimResult, expected: dict[str, np.ndarray]) -> None:
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(result, name), expected[name], err_msg=name)


def address(result: SimResult) -> int:
    return int(result.offset.ctypes.data)


@pytest.fixture(autouse=True)
def empty_pool() -> Iterator[None]:
    release_memory()
    yield
    release_memory()


def test_a_dropped_result_s_block_serves_the_next_call_with_that_call_s_values() -> None:
    first = simulate("adaptive", trace(BIG, 0), DT, PARAMS)
    block = address(first)
    del first
    force = trace(BIG, 1)
    second = simulate("adaptive", force, DT, PARAMS)
    assert address(second) == block
    assert_equals(second, oracle(force))


@settings(max_examples=8, deadline=None)
@given(kept=st.sampled_from(FIELDS), sliced=st.booleans(), seed=st.integers(0, 2**16))
def test_a_block_is_never_reused_while_any_array_of_it_lives(
    kept: str, sliced: bool, seed: int
) -> None:
    force = trace(BIG, seed)
    result = simulate("adaptive", force, DT, PARAMS)
    block = address(result)
    array = getattr(result, kept)
    held = array[BIG // 2 :: 3, 1:] if sliced else array  # a view of a view keeps it too
    expected = held.copy()
    del result, array
    other = simulate("adaptive", trace(BIG, seed + 1), DT, PARAMS)
    assert address(other) != block
    del other
    np.testing.assert_array_equal(held, expected)
    del held
    assert address(simulate("adaptive", force, DT, PARAMS)) == block  # the newest that fits


def test_a_block_serves_requests_from_half_its_size_to_its_size() -> None:
    larger = simulate("adaptive", trace(2 * BIG, 0), DT, PARAMS)
    block, size = address(larger), larger.offset.nbytes
    del larger
    assert address(simulate("adaptive", trace(2 * BIG + 1, 1), DT, PARAMS)) != block
    assert address(simulate("adaptive", trace(BIG - 1, 2), DT, PARAMS)) != block
    force = trace(BIG, 3)
    smaller = simulate("adaptive", force, DT, PARAMS)
    assert address(smaller) == block
    assert smaller.offset.nbytes < size
    assert_equals(smaller, oracle(force))


def test_small_results_are_left_to_malloc() -> None:
    small = simulate("adaptive", trace(BIG - 1, 0), DT, PARAMS)
    del small
    assert release_memory() == 0


def test_the_pool_keeps_the_newest_blocks_within_its_cap(monkeypatch: pytest.MonkeyPatch) -> None:
    sizes = [ticks_for(n << 20) for n in (40, 36, 33)]
    nbytes = [t * AXES * 33 for t in sizes]
    monkeypatch.setattr(pool, "CAP_BYTES", nbytes[1] + nbytes[2])
    results = [simulate("adaptive", trace(t, i), DT, PARAMS) for i, t in enumerate(sizes)]
    while results:  # dropped oldest first: the 40 MiB block is released, the other two kept
        results.pop(0)
    assert release_memory() == nbytes[1] + nbytes[2]
    assert release_memory() == 0


def test_a_failed_simulate_gives_its_block_back() -> None:
    force = trace(BIG, 0)
    force[BIG // 2, 4] = np.nan
    with pytest.raises(
        NonFiniteForceError, match=rf"^force\[{BIG // 2}, 4\] is nan: non-finite force is refused"
    ):
        simulate("adaptive", force, DT, PARAMS)
    assert release_memory() == BIG * AXES * 33


def test_threads_sharing_the_pool_each_get_their_own_values() -> None:
    forces = [trace(BIG + 1000 * i, i) for i in range(3)]
    expected = [oracle(f) for f in forces]
    failures: list[BaseException] = []

    def work(i: int) -> None:
        try:
            for _ in range(4):
                assert_equals(simulate("adaptive", forces[i], DT, PARAMS), expected[i])
        except BaseException as error:  # reported by the main thread
            failures.append(error)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert failures == []


def _child_offsets_sum(force: np.ndarray, answer: "multiprocessing.SimpleQueue[float]") -> None:
    answer.put(float(simulate("adaptive", force, DT, PARAMS).offset.sum()))


def test_a_forked_child_does_not_inherit_a_held_lock_or_blocks() -> None:
    force = trace(BIG, 0)
    del_me = simulate("adaptive", force, DT, PARAMS)
    del del_me  # the parent now holds a pooled block
    context = multiprocessing.get_context("fork")
    answer = context.SimpleQueue()
    with pool._lock:  # as if another thread were inside take when the worker forked
        child = context.Process(target=_child_offsets_sum, args=(force, answer))
        child.start()
        child.join(timeout=120)  # a bound, not a timing: the child deadlocks without the reset
    if child.is_alive():
        child.kill()
        child.join()
    assert child.exitcode == 0
    assert answer.get() == float(oracle(force)["offset"].sum())
    assert release_memory() == BIG * AXES * 33  # the parent's block is still its own
