"""A carried load on motion no calibration log with that load covered.

The thresholds' false-alarm rate holds for motion like the calibration logs' (the motion
envelope, :mod:`impactcli.detect.envelope`). With logs that carried different loads, the
rate under a load was measured on the motion of the log that carried it only: the union
of every log's envelope says nothing of that load on another log's motion. A simulated
arm (robot 7) carrying its loaded calibration log's 1 kg in point-to-point moves raised
70 static-loading alarms of 1–2.5 N that nothing marked — the unloaded logs had moved so,
the loaded one (a multi-sine) had not — while the same load in the loaded log's motion
raised none.

So ``calibrate`` records, per log whose load differs from the model's and turns some joint
to a tenth of its loading threshold, the envelope of the logs that carried that load
(``calibration.load_envelopes``); ``detect`` checks the motion against each beside the
union's (:class:`~impactcli.detect.envelope.EnvelopeCheck` ``loads``), and an incident that
starts while the arm carries that log's load (the start's or a payload change's: the
calibration log whose fitted load the weighing took, else the one nearest in mass) and
touches motion outside that envelope is marked ``load_motion``: its rate was not measured
there. A caveat, like ``outside_envelope``: the incident stays
counted and gated. Pure functions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["carried_spans", "mark_load_motion", "nearest_load"]


def carried_spans(start: tuple[str | None, float | None], changes: Sequence[Any],
                  t_end: float, loads: Mapping[str, float], others: Sequence[float]
                  ) -> list[tuple[float, float, str, float]]:
    """The stretches (from [s], to [s], calibration log, mass [kg]) where the arm carried a
    calibration log's load: from the log's start (``start``: the calibration log whose
    load the weighing took, and the mass it weighed; (None, None): none weighed), from a
    payload change's onset (``t_start``) to the next one's (or ``t_end``), each by the
    load after it (its ``as_log`` and ``mass_after_kg``); the log is the one taken, else
    :func:`nearest_load`'s."""
    marks = [(0.0, *start)] + [(float(c.t_start), getattr(c, "as_log", None),
                                getattr(c, "mass_after_kg", None)) for c in changes]
    ends = [t for t, _, _ in marks[1:]] + [t_end]
    out = []
    for (t, log, kg), z in zip(marks, ends, strict=True):
        name = log if log is not None else nearest_load(kg, loads, others)
        if name is not None:
            out.append((t, z, name, float(kg) if kg is not None and log is None
                        else float(loads.get(name, kg or 0.0))))
    return out


def nearest_load(mass_kg: float | None, loads: Mapping[str, float], others: Sequence[float]
                 ) -> str | None:
    """The calibration log of ``loads`` (log → its load beyond the model's [kg], those
    with an envelope of their own) whose load is nearest ``mass_kg`` in mass, when it is
    nearer than every load of ``others`` (the calibration's loads without an envelope of
    their own: the model's, 0, among them); None otherwise. A weighing's standard error
    counts its rows as independent, so a load weighed at 0.959 ± 0.011 kg is not told from
    a calibrated 0.998 kg by it: the nearest calibrated load is the one the arm most likely
    carries."""
    if mass_kg is None or not loads:
        return None
    log, kg = min(loads.items(), key=lambda it: abs(it[1] - mass_kg))
    near = abs(kg - mass_kg)
    return log if all(near < abs(o - mass_kg) for o in (0.0, *others)) else None


def mark_load_motion(incidents: Sequence[Any], spans: Sequence[tuple[float, float, str, float]],
                     shares: Mapping[str, Any]) -> list[Any]:
    """The incidents (frozen dataclasses with a ``load_motion`` field), each counted one
    that starts in a span of :func:`carried_spans` and touches motion outside that log's
    envelope (``shares``: log → its :class:`~impactcli.detect.envelope.EnvelopeShare`)
    marked ``{log, mass_kg, text}`` (the span's mass, beyond the model's load: the
    calibration log's fitted load when the weighing took it as that log's, else the mass
    weighed in the log)."""
    out = []
    for inc in incidents:
        hit = next(((log, kg) for a, z, log, kg in spans if a <= inc.t_start < z
                    and log in shares and inc.number is not None
                    and shares[log].touches(inc.t_start, inc.t_end)), None)
        if hit is None:
            out.append(inc)
            continue
        log, kg = hit
        out.append(dataclasses.replace(inc, load_motion={
            "log": log, "mass_kg": kg,
            "text": (f"while the arm carried {kg:+.3g} kg beyond the model's load "
                     f"(taken as {log}'s load) on motion no calibration log with that load "
                     "covered: the thresholds' false-alarm rate was not measured for that "
                     "load on such motion")}))
    return out
