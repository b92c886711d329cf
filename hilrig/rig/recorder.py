"""The recorder, kept importable for the modules not yet moved to :mod:`hilrig.rig`."""

from hilrig.rig.recorder_feed import RecorderFeed
from hilrig.rig.recorder_process import RecorderProcess

__all__ = ["RecorderFeed", "RecorderProcess"]
