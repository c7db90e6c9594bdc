"""A payload change in words, as every output says it (the terminal, the report, the Rerun
recording and the timeline's readers): its mass, what its tests found, how a contact in its
alarm was judged, and the load it leaves the arm carrying. Pure functions of a change's
``to_dict`` (:class:`impactcli.detect.payload_finding.PayloadChange`); the monitor that finds
the changes is :mod:`impactcli.detect.payload_change` (docs/method.md §5c)."""

from __future__ import annotations

from typing import Any

from ..types import GRAVITY_M_S2

#: How ``as_log`` names the model's own load when its fit has one load for all logs.
OWN_LOAD = "the model's own"


def whose_load(as_log: str) -> str:
    """Whose load a change's ``as_log`` names, as every output says it."""
    return "the model's own load" if as_log == OWN_LOAD else f"{as_log}'s load, as fitted"


def watch_text(watch: dict[str, Any]) -> str:
    """A change's ``contact_watch`` in words, as every output says it: ``a contact in its
    alarm not told from the load 20.044–20.604 s and 23.044–23.604 s, and 20.604–23.044 s
    only above 2× the loading thresholds``."""
    (a, b), (c, d) = watch["unjudged_s"]
    lo, hi = watch["above_s"]
    return (f"a contact in its alarm not told from the load {a:.3f}–{b:.3f} s and "
            f"{c:.3f}–{d:.3f} s, and {lo:.3f}–{hi:.3f} s only above "
            f"{watch['above_times_vl']:g}× the loading thresholds")


def tested_text(change: dict[str, Any]) -> str:
    """What a change's tests found (its ``to_dict``), as every output says it: ``99.7 % of
    the step a mass, steady within 1.7 %, its inertia shows`` — or ``… its inertia not seen
    (a steady press along gravity would look the same)``; a timeline from before the drift
    and inertia were written gives the share only."""
    parts = [f"{100 * change['explained']:.1f} % of the step a mass"]
    if "drift" in change:
        parts.append(f"steady within {100 * change['drift']:.2g} %")
    if change.get("inertia") == "shows":
        parts.append("its inertia shows")
    elif change.get("inertia") == "unseen":
        parts.append("its inertia not seen (a steady press along gravity would look the same)")
    seen = change.get("contact")
    if seen:
        parts.append(f"and a contact in its window that the mass does not explain (from "
                     f"{seen['t_s']:.3f} s, {seen['joint']} at {seen['peak']:.2g}× its loading "
                     "threshold): " + ("counted as an incident" if seen.get("counted", True)
                                       else "no incident holds it (see the lasting loads)"))
    text = ", ".join(parts)
    watch = change.get("contact_watch")
    return text if not watch else f"{text}; {watch_text(watch)}"


def change_text(change: dict[str, Any]) -> str:
    """A change's mass and what its tests found, as every output says it: ``+0.994 kg
    (s.e. ≥ 0.0044 kg; 99.7 % of the step a mass, …)`` — the standard error counts the
    window's noise and its rows' correlation, not the model's own error, so it is a lower
    bound (:func:`impactcli.model.payload.estimate`) — and, for an alarm already on
    when the watch began, that the change may be earlier (and, when the log's start could
    not weigh its load, that it is most likely that load), and for a load already in all
    the motion kept before its alarm (``carried_since_s``), that it came then or before."""
    early = ("; the alarm was on when the watch began: the change may be earlier, in the "
             "warm-up" if change.get("at_watch_start") else "")
    if change.get("start_unknown"):  # the start's own load, weighed late: not a pick
        early += (" — and the log's first seconds could not weigh the load it started with: "
                  if early else "; the log's first seconds could not weigh the load it "
                  "started with, yet found about this mass in part: ") + (
                      "most likely that load, carried from the start, not one picked")
    if (since := change.get("carried_since_s")) is not None:  # a step under vL
        early += (f"; NOT a step at this time: the load is in all the motion kept before "
                  f"it, from {since:.3f} s, so it was picked or released then or before and "
                  "its torque passed the thresholds here as the motion grew it — or a contact "
                  "did")
    return (f"{change['mass_kg']:+.3g} kg (s.e. ≥ {change['mass_se_kg']:.2g} kg; "
            f"{tested_text(change)}{early})")


def beyond_words(mass_kg: float) -> tuple[str, str]:
    """A load's mass against the model's, as every output says it: (``+3``, ``beyond``)
    or, for a lighter one, (``1.2``, ``less than``) — never a negative mass carried."""
    return ((f"{mass_kg:+.3g}", "beyond") if mass_kg >= 0 else
            (f"{-mass_kg:.3g}", "less than"))


def carrying_text(change: dict[str, Any]) -> str:
    """The load a change (its ``to_dict``) leaves the arm carrying, as every output says
    it: ``+3 kg beyond the model's load`` (``1.2 kg less than …`` for a lighter one; with
    its ``mass_check`` when the release took off more than the log was seen to carry),
    ``… : heavy.csv's load, as fitted`` when it is a calibration log's (``as_log``), or
    ``the model's own load``."""
    known = change.get("as_log")
    if known == OWN_LOAD:
        return whose_load(OWN_LOAD)
    kg, side = beyond_words(float(change["mass_after_kg"]))
    check = change.get("mass_check")
    return (f"{kg} kg {side} the model's load"
            + ("" if known is None else f": {whose_load(str(known))}")
            + ("" if not check else f" ({check})"))


def press_text(change: dict[str, Any]) -> str | None:
    """Why a change (its ``to_dict``) was not told from a contact, or None: its inertia did
    not show — then a steady press of |m| g along gravity at its centre of mass gives the
    same torque (a clamp pressing the arm down; for a release, its end, or one pressing up) —
    or its release took off more than the log was seen to carry (``mass_check``: its mass
    cannot be trusted). The gates could not judge such a change; the verdict says why."""
    if change.get("inertia") == "unseen":
        f = f"~{press_force_n(change):.2g} N"
        return ("its inertia did not show, so " + (
            f"a steady press of {f} down along gravity (a clamp) would look the same"
            if change["mass_kg"] > 0 else f"the end of a steady press of {f} down along "
            "gravity (a clamp released), or one up, would look the same"))
    if change.get("mass_check"):
        return "it released more than the log was seen to carry, so its mass cannot be trusted"
    return None


def press_force_n(change: dict[str, Any]) -> float:
    """The steady press along gravity a change's mass step equals [N] (|m| g)."""
    return GRAVITY_M_S2 * abs(float(change["mass_kg"]))
