"""The loop's tick: everything between "newest sample" and "joint targets", as the live loop and
the closed-loop replay both run it.

:mod:`.step_kernel` (the compiled tick: compensation, base frame, controller, IK, clamp),
:mod:`.kernel` (:class:`~hilrig.tick.kernel.CompiledTick` over its arrays, bound by address),
:mod:`.loop_step` (the live loop's tick: its inputs' freshness and what changed, in the same
compiled call), :mod:`.row` (the tick's recorder row), :mod:`.safety` and :mod:`.clamp_kernels` (the
safety clamp: its configuration, reference path and compiled kernels), :mod:`.trajectory` (the task
trajectories X_d(t)), :mod:`.links` (the links' names in the loop's events and how long a failed
command holds, which replay reads back). It sits below the rig and replay, which import it, and
above control, the drivers' compensation and the robot model, which it composes.
"""
