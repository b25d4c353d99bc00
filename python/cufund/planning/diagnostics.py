"""Per-replan planner diagnostics, published on :data:`PLANNER_DIAGNOSTICS` (``/planner/diagnostics``) next to
the trajectory updates, and kept for the run's ``metrics.json``."""

from __future__ import annotations

from cufund.core.messages import Message, message
from cufund.core.topics import Topic

__all__ = ["PLANNER_DIAGNOSTICS", "PlannerDiagnostics"]


@message
class PlannerDiagnostics(Message):
    """One (re)plan of a planner."""

    t: float
    """Simulated time of the replan [s]."""
    planner: str
    """The planner's kind ("local", "global")."""
    status: str
    """"ok", or why the plan was rejected ("collision", a path-search status, ...); "at_goal"."""
    plan_ms: float
    """Wall time of the replan [ms]."""
    plan_cpu_ms: float
    """CPU time of the replan [ms] (the wall time less preemption by other processes)."""
    min_clearance_m: float
    """Smallest certified map clearance of the candidate trajectory [m]."""
    path_length_m: float
    """Length of the accepted trajectory [m] (0 when rejected)."""


PLANNER_DIAGNOSTICS = Topic("/planner/diagnostics", PlannerDiagnostics)
"""Where planners publish their :class:`PlannerDiagnostics`."""
