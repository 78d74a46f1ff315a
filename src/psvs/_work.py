"""Time estimates made before long work, so a command refuses in one line instead of running for hours.

A count a user types (frames, views, cycles) times the cost of one (a render, a control cycle) is the time
the command would take. Work estimated beyond :data:`WORK_LIMIT_S` is refused before it starts, saying the
estimate and the limit (the memory side is :mod:`psvs._memory`).
"""
from __future__ import annotations

#: The longest a command may plan to work, s.
WORK_LIMIT_S = 3600.0


def duration(seconds: float) -> str:
    """Seconds in the largest fitting unit, e.g. ``45 s``, ``12.5 min``, ``34.1 h``, ``2.3e+04 days``."""
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            value = f"{seconds / size:.3g}"
            return f"{value} {'day' if unit == 'days' and value == '1' else unit}"
    return f"{seconds:.3g} s"


def check_time(seconds: float, what: str, hint: str = "", limit_s: float | None = None) -> None:
    """ValueError "<what> takes about <estimate>, more than the <limit> limit; <hint>" when ``seconds``
    exceeds ``limit_s`` (default :data:`WORK_LIMIT_S`). ``what`` names the options the user typed and how the
    estimate follows from them."""
    limit = WORK_LIMIT_S if limit_s is None else float(limit_s)
    if not seconds <= limit:   # NaN and inf too
        tail = f"; {hint}" if hint else ""
        raise ValueError(f"{what} takes about {duration(seconds)}, more than the {duration(limit)} limit{tail}")
