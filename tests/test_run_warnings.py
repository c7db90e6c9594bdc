"""The run's warnings name what a reader must not miss (impactcli/run/run_warnings.py)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

from impactcli.run.run_warnings import warn_defect_incidents, warn_late_warmup


@dataclass(frozen=True)
class _Alarm:
    t_start: float
    force_n: float | None
    force_at_least: bool = False
    data_defect: dict[str, Any] | None = None


def _said(fn: Any, *args: Any) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn(*args)
    return [str(w.message) for w in caught]


def test_a_late_warm_up_names_its_largest_alarm_beyond_the_first_five() -> None:
    """A new user's trial: 18 alarms in a warm-up that ran to its cap; the five named were
    1.5-5.5 N and the 23 N one at 10.032 s (a labelled 30 N push) was among "13 more".
    The largest is now named; when it is among the first five, nothing is added."""
    late = [_Alarm(3.2 + 0.5 * k, 2.0 + k * 0.1) for k in range(7)] + [_Alarm(10.032, 23.3)]
    (msg,) = _said(warn_late_warmup, "x.csv", late, 3.0, 20.0, 60.0)
    assert "and 3 more; the largest at 10.032 s ~23.3 N) — a contact there" in msg, msg
    (msg,) = _said(warn_late_warmup, "x.csv", late[-1:] + late[:6], 3.0, 20.0, 60.0)
    assert "the largest" not in msg and "at 10.032 s ~23.3 N, 3.200 s" in msg, msg


def test_incidents_at_a_defect_say_the_adaptive_memory_in_seconds() -> None:
    """An incident 4.5 s after a jump is marked when the adaptive detector alone raised it
    within its memory: the warning says how long that memory is (a new user read "within
    0.56 s after it" beside incidents seconds later)."""
    inc = [_Alarm(4.468, 2.3, data_defect={"kind": "jump", "t_start": 0.012})]
    (msg,) = _said(warn_defect_incidents, "x.csv", [], inc, 0.56, 12.0)
    assert ("1 incident(s) start at a data defect or within 0.56 s after it (the adaptive "
            "detector's alone: within its memory, 12 s; 4.468 s (jump))") in msg, msg
