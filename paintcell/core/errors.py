"""Project exceptions for planning. Each message is one line naming the problem and the fix."""


class PaintcellError(Exception):
    """Base of every paintcell error that a user can fix by changing input or settings."""


def one_line(exc: BaseException, limit: int | None = None) -> str:
    """The first line of an exception's message, at most `limit` characters (its type name when
    the message is empty)."""
    lines = str(exc).strip().splitlines()
    return lines[0][:limit] if lines else type(exc).__name__


class SurfaceError(PaintcellError):
    """A mesh or parametric surface cannot be used (empty, NaN, degenerate, non-manifold, ...)."""


class ApplicatorError(PaintcellError):
    """Applicator (deposition model) parameters are invalid."""


class PlanError(PaintcellError):
    """A coverage plan cannot be built, loaded, or is inconsistent."""


class AxisTurnError(PlanError):
    """The bell axis cannot follow the surface along a pass within `max_axis_turn_rad_m` (a
    crease or fold tighter than the smoothing scale). `plan_coverage` with `smoothing_m = "auto"`
    plans again at larger smoothing scales when it meets this error."""


class ScenarioError(PaintcellError):
    """A scenario cannot be found, loaded or is inconsistent."""


class ScenarioDataError(PaintcellError):
    """A scenario file or snapshot holds an unknown key or an invalid value."""
