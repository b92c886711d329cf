"""Algorithm 2 contact states on scripted traces (preset 'adaptive' at 1 kHz).

Timing of the preset: debounce 4 ticks, release 50 ticks, holding after 500 ticks of contact.
"""

import numpy as np

from hilrig.control import ContactState, simulate

DT = 0.001
FREE, CONTACT, HOLDING, RECOVERING = (int(s) for s in ContactState)


def trace(*segments: tuple[int, float]) -> np.ndarray:
    """A one-axis force trace from (ticks, newtons) segments."""
    return np.concatenate([np.full(n, f) for n, f in segments])[:, None]


def run(force: np.ndarray):
    return simulate("adaptive", force, DT, "adaptive")


def test_contact_needs_the_debounce_and_a_short_spike_changes_nothing() -> None:
    spike = run(trace((100, 0.0), (3, 5.0), (200, 0.0)))
    assert (spike.contact == FREE).all()
    assert (spike.damping == 150.0).all()
    assert (spike.stiffness == 300.0).all()
    contact = run(trace((100, 0.0), (10, 5.0)))
    states = contact.contact[:, 0]
    assert (states[:103] == FREE).all()
    assert (states[103:] == CONTACT).all()
    assert contact.damping[103, 0] == 120.0  # the adaptive law takes over on entering contact


def test_sustained_contact_holds_the_avoidance_pose() -> None:
    # 3 N pushes for 0.7 s, then eases to 1 N (still contact): stiffness must not rise back.
    result = run(trace((10, 0.0), (700, 3.0), (300, 1.0)))
    states = result.contact[:, 0]
    assert states[10 + 3 + 499] == CONTACT
    assert states[10 + 3 + 500] == HOLDING
    assert (states[513:] == HOLDING).all()
    holding_k = result.stiffness[513:, 0]
    assert (np.diff(holding_k) <= 0).all()
    # ...whereas the bare law would have let it rise as the force eased
    bare = simulate("adaptive", trace((10, 0.0), (700, 3.0), (300, 1.0)), DT, "paper-end-effector")
    assert bare.stiffness[-1, 0] > holding_k[-1]


def test_release_recovers_to_nominal_and_then_free() -> None:
    result = run(trace((10, 0.0), (300, 4.0), (6000, 0.0)))
    states = result.contact[:, 0]
    release_tick = 310 + 49  # 50 ticks below delta
    assert states[release_tick - 1] == CONTACT
    assert states[release_tick] == RECOVERING
    assert result.damping[release_tick, 0] == 150.0
    k = result.stiffness[release_tick:, 0]
    assert (np.diff(k) >= 0).all() and k[-1] == 300.0
    free = np.flatnonzero(states == FREE)
    back = free[free > release_tick][0]
    # free again only once the offset is within the settle tolerance (1 mm)
    assert abs(result.offset[back - 1, 0]) <= 1e-3
    assert abs(result.offset[back - 2, 0]) > 1e-3 or result.stiffness[back - 2, 0] < 300.0
    assert (states[back:] == FREE).all()


def test_contact_again_during_recovery_re_enters_contact() -> None:
    result = run(trace((10, 0.0), (300, 4.0), (100, 0.0), (50, -4.0)))
    states = result.contact[:, 0]
    assert RECOVERING in states[310:410]
    assert (states[410 + 3 :] == CONTACT).all()
    assert result.damping[-1, 0] == 120.0


def test_groups_keep_their_own_state() -> None:
    from hilrig.control import combine, preset

    params = combine((preset("adaptive"), 1), (preset("adaptive-joint"), 1))
    force = np.zeros((50, 2))
    force[:, 1] = 3.0
    result = simulate("adaptive", force, DT, params)
    assert (result.contact[:, 0] == FREE).all()
    assert result.contact[-1, 1] == CONTACT


def test_without_the_state_machine_contact_is_reported_per_tick() -> None:
    result = simulate("adaptive", trace((5, 0.0), (2, 1.0), (5, 0.0)), DT, "paper-end-effector")
    assert result.contact[:, 0].tolist() == [FREE] * 5 + [CONTACT] * 2 + [FREE] * 5
