"""Payload changes scored against ground truth (docs/formats.md, "Ground-truth labels").

The labels may list the loads picked and released (``payload_changes``: each ``t_s``, the
step's time [s], and ``mass_kg``, the change of the load carried [kg]; the simulator writes
them). A change the run found (the timeline's ``payload_changes``) matches a labelled one
of the same sign whose step lies within :data:`TIME_S` of its onset, the nearest first, one
each. A match is *right* when its mass lies within :data:`MASS_SHARE` of the labelled
change's — the bar tests/test_payload.py holds the monitor to. Labelled changes no found one
matches are missed; found ones no labelled one matches are unlabelled (a load the labels do
not have, or an alarm taken for one).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

#: A found change's onset within this many seconds of a labelled step matches it.
TIME_S = 1.0
#: A matched change is right when its mass is within this share of the labelled change's.
MASS_SHARE = 0.25


def labelled_steps(labelled: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The labelled changes there is something to find in (a change of no mass is none)."""
    return [x for x in labelled if float(x["mass_kg"]) != 0.0]


def score_payload_changes(found: Sequence[dict[str, Any]],
                          labelled: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The evaluation's ``payload_changes`` mapping (module docstring): ``labelled`` and
    ``found`` counts, ``matched`` rows (labelled ``t_s`` and ``mass_kg``, the found
    ``t_start`` and ``mass_kg``, ``dt_s`` = found − labelled, ``mass_error`` (found −
    labelled) / |labelled|, ``right``), the ``missed`` labelled steps, the ``unlabelled``
    found onsets (``start_unknown`` when the run took one for the load the log started
    with), ``right`` (how many), and the bars ``time_s`` and ``mass_share``."""
    free = list(range(len(found)))
    matched, missed = [], []
    steps = labelled_steps(labelled)
    for lab in sorted(steps, key=lambda x: float(x["t_s"])):
        t, kg = float(lab["t_s"]), float(lab["mass_kg"])
        near = [k for k in free if abs(float(found[k]["t_start"]) - t) <= TIME_S
                and (float(found[k]["mass_kg"]) > 0) == (kg > 0)]
        if not near:
            missed.append({"t_s": t, "mass_kg": kg})
            continue
        k = min(near, key=lambda i: abs(float(found[i]["t_start"]) - t))
        free.remove(k)
        m = float(found[k]["mass_kg"])
        err = (m - kg) / abs(kg)
        matched.append({"t_s": t, "mass_kg": kg, "t_start": float(found[k]["t_start"]),
                        "found_mass_kg": m, "dt_s": float(found[k]["t_start"]) - t,
                        "mass_error": err, "right": abs(err) <= MASS_SHARE})
    return {"labelled": len(steps), "found": len(found), "matched": matched,
            "missed": missed,
            "unlabelled": [{"t_start": float(found[k]["t_start"]),
                            "mass_kg": float(found[k]["mass_kg"]),
                            **({"start_unknown": True} if found[k].get("start_unknown")
                               else {})} for k in free],
            "right": sum(1 for m in matched if m["right"]),
            "time_s": TIME_S, "mass_share": MASS_SHARE}


def payload_text(score: dict[str, Any]) -> str:
    """One line for ``evaluate``: ``payload changes: 2/2 found and right (onset within 1 s,
    mass within 25 %): +2 kg at 20.05 s for +2 kg at 20 s, …; none found where none was
    labelled`` (else each one found so: false, or most likely the start's own load) — or,
    for a run that did not look for loads (``watched`` false), that it did not."""
    if score.get("watched") is False:
        return (f"payload changes: {score['labelled']} labelled, not scored: this run did "
                "not look for loads (it takes a calibrated config and a model with "
                "kinematics whose residual can carry a load — the tool's own, or a "
                "controller's channel corrected by it; detect said why it could not: "
                "docs/method.md §5c)")
    rows = [f"{m['found_mass_kg']:+.3g} kg at {m['t_start']:.2f} s for {m['mass_kg']:+.3g} kg "
            f"at {m['t_s']:g} s" + ("" if m["right"] else " (mass off)")
            for m in score["matched"]]
    rows += [f"missed {m['mass_kg']:+.3g} kg at {m['t_s']:g} s" for m in score["missed"]]
    return (f"payload changes: {score['right']}/{score['labelled']} found and right (onset "
            f"within {score['time_s']:g} s, mass within {100 * score['mass_share']:.0f} %)"
            + (f": {'; '.join(rows)}" if rows else "")
            + ("; none found where none was labelled" if not score["unlabelled"] else
               f"; {len(score['unlabelled'])} found where none was labelled: "
               + "; ".join(f"{u['mass_kg']:+.3g} kg at {u['t_start']:.2f} s "
                           + ("(most likely the load the log started with, which its start "
                              "could not weigh)" if u.get("start_unknown") else "(false)")
                           for u in score["unlabelled"])))
