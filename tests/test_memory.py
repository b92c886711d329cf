"""Fresh memory populated on another core (hilrig/memory.py): small arrays are np.empty's, large
ones an anonymous mapping a thread populates without changing what is written meanwhile, and
``simulate``'s outputs there equal the kernel's into memory in use."""

from __future__ import annotations

import os
import platform

import numpy as np
import pytest

from hilrig import memory
from hilrig.control import combine, make, preset, simulate
from hilrig.control.axis import OUTPUTS

PAGE = os.sysconf("SC_PAGE_SIZE")


def resident_bytes() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * PAGE


def kernel_at_least(major: int, minor: int) -> bool:
    release = platform.release().split(".")
    return (int(release[0]), int(release[1].split("-")[0])) >= (major, minor)


def test_a_small_array_is_numpys_own_and_has_no_thread() -> None:
    array, thread = memory.fresh((10, 3), np.float64)
    assert thread is None and array.shape == (10, 3) and array.flags.owndata


def test_a_large_array_keeps_what_is_written_while_it_is_populated() -> None:
    shape = (4, memory.MIN_BYTES // 8 // 4 + 1000)
    array, thread = memory.fresh(shape, np.float64)
    assert thread is not None
    assert array.shape == shape and array.dtype == np.float64 and array.flags.writeable
    values = np.arange(array.size, dtype=np.float64).reshape(shape)
    array[...] = values  # while the thread populates the same pages
    thread.join()
    assert np.array_equal(array, values)


@pytest.mark.skipif(
    platform.system() != "Linux" or not kernel_at_least(5, 14),
    reason="MADV_POPULATE_WRITE is Linux 5.14+",
)
def test_the_thread_makes_the_memory_resident_without_the_caller_touching_it() -> None:
    before = resident_bytes()
    array, thread = memory.fresh((4 * memory.MIN_BYTES // 8,), np.float64)
    assert thread is not None
    thread.join()
    assert resident_bytes() - before >= 0.9 * array.nbytes


def test_simulate_into_fresh_memory_equals_the_kernel_into_memory_in_use() -> None:
    rng = np.random.default_rng(7)
    force = rng.normal(scale=2.0, size=(60_000, 9))  # 17 MB of outputs: over MIN_BYTES
    force[20_000:21_500, 2] += 6.0 * np.sin(np.linspace(0.0, np.pi, 1500))
    params = combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6))
    result = simulate("adaptive", force, 1e-3, params)
    out = np.zeros((len(OUTPUTS), *force.shape))
    contact = np.zeros(force.shape, dtype=np.int8)
    make("adaptive", params, dt=1e-3).at_rest().run_into(force, out, contact)
    for name, column in zip(OUTPUTS, out, strict=True):
        assert np.array_equal(getattr(result, name), column), name
    assert np.array_equal(result.contact, contact)
    assert not result.offset.flags.owndata  # the fresh mapping's, not np.empty's
