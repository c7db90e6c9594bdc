"""A carried load on motion its calibration log did not cover.

The thresholds' false-alarm rate holds for motion like the calibration logs' (the motion
envelope, :mod:`impactcli.detect.envelope`). With logs that carried different loads, the
rate under a load was measured on the motion of the log that carried it only: the union
of every log's envelope says nothing of that load on another log's motion. A simulated
arm (robot 7) carrying its loaded calibration log's 1 kg in point-to-point moves raised
70 static-loading alarms of 1–2.5 N that nothing marked — the unloaded logs had moved so,
the loaded one (a multi-sine) had not — while the same load in the loaded log's motion
raised none.

So ``calibrate`` records, per log whose load differs from the model's and turns some joint
to a tenth of its loading threshold, that log's own envelope
(``calibration.load_envelopes``); ``detect`` checks the motion against each beside the
union's (:class:`~impactcli.detect.envelope.EnvelopeCheck` ``loads``), and an incident that
starts while the arm carries that log's load (the start's, or a payload change's
``as_log``) and touches motion outside that log's envelope is marked ``load_motion``: its
rate was not measured there. A caveat, like ``outside_envelope``: the incident stays
counted and gated. Pure functions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["carried_spans", "mark_load_motion"]


def carried_spans(start_as_log: str | None, changes: Sequence[Any], t_end: float
                  ) -> list[tuple[float, float, str]]:
    """The stretches (from [s], to [s], calibration log) where the arm carried a
    calibration log's load: from the log's start while its start load is one
    (``start_as_log``), from a payload change's onset (``t_start``) to the next one's (or
    ``t_end``) while the load after it is one (its ``as_log``)."""
    marks = [(0.0, start_as_log)] + [(float(c.t_start), getattr(c, "as_log", None))
                                     for c in changes]
    ends = [t for t, _ in marks[1:]] + [t_end]
    return [(t, z, log) for (t, log), z in zip(marks, ends, strict=True) if log is not None]


def mark_load_motion(incidents: Sequence[Any], spans: Sequence[tuple[float, float, str]],
                     shares: Mapping[str, Any], masses: Mapping[str, float]) -> list[Any]:
    """The incidents (frozen dataclasses with a ``load_motion`` field), each counted one
    that starts in a span of :func:`carried_spans` and touches motion outside that log's
    envelope (``shares``: log → its :class:`~impactcli.detect.envelope.EnvelopeShare`)
    marked ``{log, mass_kg, text}`` (``masses``: log → its load beyond the model's)."""
    out = []
    for inc in incidents:
        hit = next((log for a, z, log in spans if a <= inc.t_start < z and log in shares
                    and inc.number is not None
                    and shares[log].touches(inc.t_start, inc.t_end)), None)
        if hit is None:
            out.append(inc)
            continue
        kg = float(masses[hit])
        out.append(dataclasses.replace(inc, load_motion={
            "log": hit, "mass_kg": kg,
            "text": (f"while the arm carried {kg:+.3g} kg beyond the model's load "
                     f"({hit}'s, as calibrated) on motion that log did not cover: the "
                     "thresholds' false-alarm rate was not measured for that load on such "
                     "motion")}))
    return out
