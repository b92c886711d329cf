"""Models of the world the robot meets: the emulated arm's servos, the emulated volunteers, and
the contact models identified from recorded collisions.

They serve both the emulated rig (:mod:`hilrig.emulator`, which plays them on its devices) and
offline prediction (closed-loop replay), so they live here, below both: :mod:`.plant` (the AUBO
joint servos), :mod:`.scenarios` (volunteer models and their settings), :mod:`.contact` (contact
mechanics fitted to a recorded collision).
"""
