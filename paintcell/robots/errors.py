"""Project exceptions for robots. Each message is one line naming the problem and the fix."""

from paintcell.core.errors import PaintcellError


class RobotError(PaintcellError):
    """A robot model cannot be loaded or used as asked (unknown name, bad array shape, ...)."""


class UnreachableError(RobotError):
    """A pose or path cannot be reached by the robot (outside the workspace or joint limits)."""
