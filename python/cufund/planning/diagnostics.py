"""Per-replan planner diagnostics, published on :data:`PLANNER_DIAGNOSTICS` (``/planner/diagnostics``) next to
the trajectory updates, and kept for the run's ``metrics.json``. The message is one of cufund's core messages
(:class:`cufund.core.messages.PlannerDiagnostics`), so a log names it without naming the planning layer."""

from __future__ import annotations

from cufund.core.messages import PlannerDiagnostics, Topics

__all__ = ["PLANNER_DIAGNOSTICS", "PlannerDiagnostics"]

PLANNER_DIAGNOSTICS = Topics.PLANNER_DIAGNOSTICS
"""Where planners publish their :class:`PlannerDiagnostics`."""
