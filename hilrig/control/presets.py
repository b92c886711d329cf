"""Named parameter sets: the paper's (section 3.4, bare law) and hilrig's defaults.

``paper-*`` presets are the paper's values with the bare law only (no Algorithm 2 state machine,
no Theorem 1 guard), so they reproduce its simulations. ``adaptive`` and ``adaptive-joint`` are
the same values with both safeguards on: what the live loop uses unless told otherwise.
"""

from __future__ import annotations

from dataclasses import replace

from hilrig.control.params import AdmittanceParams
from hilrig.errors import ParameterError

PAPER_END_EFFECTOR = AdmittanceParams(
    m=20.0, b_d=150.0, k_d=300.0, a1=20.0, a2=0.7, beta=30.0, delta=0.2
)
PAPER_JOINT = AdmittanceParams(m=30.0, b_d=40.0, k_d=150.0, a1=6.0, a2=0.7, beta=10.0, delta=0.2)

PRESETS: dict[str, AdmittanceParams] = {
    "paper-end-effector": PAPER_END_EFFECTOR,
    "paper-joint": PAPER_JOINT,
    "adaptive": replace(PAPER_END_EFFECTOR, state_machine=True, rate_guard=True),
    "adaptive-joint": replace(PAPER_JOINT, state_machine=True, rate_guard=True),
}

PAPER_DT_S = 0.002  # the paper's sample time (section 3.4)


def preset(name: str) -> AdmittanceParams:
    """The preset called ``name``; raises ParameterError listing the known names."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ParameterError(
            f"unknown preset {name!r}; known: {', '.join(sorted(PRESETS))}"
        ) from None
