"""The loop's tick: everything between "newest sample" and "joint targets", as the live loop and
the closed-loop replay both run it.

:mod:`.kernel` (the compiled tick: compensation, base frame, controller, IK, clamp, and
:class:`~hilrig.tick.kernel.CompiledTick` over its arrays), :mod:`.row` (the tick's recorder
row), :mod:`.safety` and :mod:`.clamp_kernels` (the safety clamp: its configuration, reference
path and compiled kernels), :mod:`.trajectory` (the task trajectories X_d(t)). It sits below the
rig and replay, which import it, and above control, the drivers' compensation and the robot
model, which it composes.
"""
