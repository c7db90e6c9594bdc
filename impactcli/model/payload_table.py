"""The calibration fit's payloads per log, in the terminal's words (docs/models.md,
"Payloads"): the table ``calibrate`` prints under the fit, what a planar arm's fitted load
says of the robot description, and the warning that the logs carried different loads. Reads
the model's ``fit.payloads`` record (:func:`impactcli.model.payload.with_log_payloads`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .payload import WEIGH_SIGMAS, alike


def describe(model: Any) -> list[str]:
    """Lines for the terminal: each calibration log's payload, beyond the lightest's."""
    rec = (model.fit or {}).get("payloads")
    if not rec:
        return []
    lines = [f"payload per log (the motion tells only differences of load: beyond "
             f"{rec['relative_to']}'s, which the model's parameters carry; ± counts the "
             "rows as independent: a lower bound)"]
    w = max(len(e["log"]) for e in rec["logs"])
    for e in rec["logs"]:
        m, s = e["values"]["m"], e["se"].get("m")
        cells = "  ".join(f"{nm} {e['values'][nm]:+.3g}" for nm in rec["parameters"][1:])
        err = "" if s is None or s == 0 else f" ± {s:.2g}"
        lines.append(f"  {e['log']:<{w}}  {m:+7.3g} kg{err}   ({cells})")
    lines += [f"  {e['log']}: {x}" for e in rec["logs"] if not alike(e)
              and (x := _off_flange(model, e["values"], e.get("se") or {})) is not None]
    return lines


#: A planar arm's load whose centre of mass lies this far beyond the described last link's
#: end (a share of its length) is said: a long tool, or a wrong link length.
OFF_FLANGE_SHARE = 0.25


def _off_flange(model: Any, values: dict[str, float], se: dict[str, float]) -> str | None:
    """What a planar arm's fitted load (its ``values`` and standard errors ``se``) says of
    the robot description, when its centre of mass along the last link lies behind the last
    joint or more than :data:`OFF_FLANGE_SHARE` of that link beyond its end, by three
    standard errors of it; None otherwise — a mass under ten of its standard errors (its
    centre is not known), or another kind (a URDF's flange frame is not known here)."""
    m = values.get("m", 0.0)
    if (model.kind != "planar" or "mx" not in values
            or m <= 0 or m <= 10 * float(se.get("m") or 0.0)):
        return None
    length = float(model.structure["link_lengths"][-1])
    c = values["mx"] / m
    c_se = float(np.hypot(float(se.get("mx") or 0.0), c * float(se.get("m") or 0.0))) / m
    far = max(-c, c - (1.0 + OFF_FLANGE_SHARE) * length)
    if far <= WEIGH_SIGMAS * c_se:
        return None
    return (f"its load's centre of mass lies {c:.2g} m along the last link, where the robot "
            f"description ends that link at {length:g} m: a long tool — or a wrong link "
            "length in the description (forces and the loads' effects scale with it)")


def differ_warning(model: Any) -> str | None:
    """The warning when the calibration logs carried different loads, else None."""
    rec = (model.fit or {}).get("payloads")
    if not rec:
        return None
    rel = rec["relative_to"]
    others = [e for e in rec["logs"] if e["log"] != rel]

    heavier = [f"{e['log']} {e['values']['m']:+.3g} kg" for e in others if not alike(e)]
    if not heavier:
        return None
    same = [e["log"] for e in others if alike(e)]
    return (f"the calibration logs carry different loads ({', '.join(heavier)} beyond "
            f"{rel}" + (f"; {', '.join(same)} within three standard errors of it" if same
                        else "")
            + f"): each log's residual used its own load; the config's model carries "
            f"{rel}'s")
