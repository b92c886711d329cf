"""The paper's simulation experiments (section 2.1 and 3.4) and their inputs.

This package imports only the force/torque profiles (numpy only), so the emulated rig's
volunteer scenarios can reuse them cheaply. The rest lives in submodules:

- ``hilrig.paper.experiments``: runs and metrics, and the paper's published numbers;
- ``hilrig.paper.report``: comparison tables (pandas, Markdown, CSV, rich);
- ``hilrig.paper.plots``: PNG figures equivalent to the paper's (matplotlib, Agg);
- ``hilrig.paper.reproduce``: all of the above into one output directory.
"""

from hilrig.paper.profiles import (
    BODY_ONSET_S,
    BODY_PROFILES,
    BODY_RELEASE_S,
    END_EFFECTOR_ONSET_S,
    END_EFFECTOR_PROFILES,
    END_EFFECTOR_RELEASE_S,
    Profile,
    Segment,
    end_effector_force,
    fx,
    fy,
    fz,
    joint_torque,
    tau1,
    tau2,
)

__all__ = [
    "BODY_ONSET_S",
    "BODY_PROFILES",
    "BODY_RELEASE_S",
    "END_EFFECTOR_ONSET_S",
    "END_EFFECTOR_PROFILES",
    "END_EFFECTOR_RELEASE_S",
    "Profile",
    "Segment",
    "end_effector_force",
    "fx",
    "fy",
    "fz",
    "joint_torque",
    "tau1",
    "tau2",
]
