"""Project exceptions for planning. Each message is one line naming the problem and the fix."""


class PaintcellError(Exception):
    """Base of every paintcell error that a user can fix by changing input or settings."""


class SurfaceError(PaintcellError):
    """A mesh or parametric surface cannot be used (empty, NaN, degenerate, non-manifold, ...)."""


class ApplicatorError(PaintcellError):
    """Applicator (deposition model) parameters are invalid."""


class PlanError(PaintcellError):
    """A coverage plan cannot be built, loaded, or is inconsistent."""
