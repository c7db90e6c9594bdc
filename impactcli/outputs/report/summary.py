"""The answer first: the verdict line of a log, its incident list, and the fleet summary.

An *incident* is one physical contact as the product sees it (docs/formats.md,
"Detection timeline", ``incidents``; :mod:`impactcli.detect.incidents`): when
(``t_start``, and ``t_start_utc`` on an epoch clock), where (``link``), how hard
(``force_n``, or without kinematics the peak residual torques), what kind (``contact``),
which detectors. The report adds only reductions of the incident's own events: its
``peak_ratio`` (the largest statistic / threshold among its events) and the detector that
reached it, and its ``label`` — its number (1, 2, … over the counted incidents, as the
terminal prints them) or ``w1``, ``w2``, … in the warm-up.

Incidents in the warm-up are listed, never counted (as events are). A lasting load (an alarm
of 10 s or more, timeline ``lasting_loads``) is a finding of its own: the verdict names it
(:func:`lasting_text`) and it is counted beside the incidents.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ...detect.aftermath import ringing_text
from ...detect.events import chained_text
from ...detect.force import (
    AT_LEAST_TEXT,
    BEYOND_LOGGED,
    FORCE_NOT_STATED,
    force_mark,
    scale_untrusted,
)
from ...detect.incidents import link_words
from ...detect.payload_words import press_force_n, press_text
from ...detect.thresholds import self_set_text, uncalibrated_blocks
from .common import (
    CONTACT_TEXT,
    PRODUCT_DETECTORS,
    approx,
    e,
    incident_score_text,
    ratio_cell,
    utc,
)

CONTACT_ORDER = ("transient", "quasi_static", "unknown")


def incident_rows(tl: dict[str, Any], period_s: float) -> list[dict[str, Any]]:
    """The timeline's incidents, each with ``number`` (1, 2, … over the counted incidents in
    time order — the timeline's own, or counted here for a timeline before 2.1 — None in the
    warm-up or at a data defect), ``label`` (the number, or ``w1``, ``w2``, … in the warm-up,
    ``d1``, ``d2``, … at a data defect), ``duration_s``,
    ``peak_ratio`` and ``peak_ratio_detector`` (over its events)."""
    events = tl.get("events") or []
    out = []
    counted = warm = marked = 0
    for inc in tl.get("incidents") or []:
        evs = [events[k] for k in inc.get("events") or [] if 0 <= k < len(events)]
        top = max(evs, key=lambda x: x["peak_ratio"], default=None)
        if inc.get("in_warmup"):
            warm += 1
            number, label = None, f"w{warm}"
        elif inc.get("data_defect"):
            marked += 1
            number, label = None, f"d{marked}"
        elif inc.get("payload_change"):  # named by its change (P1's alarm: p1)
            number, label = None, f"p{inc['payload_change']}"
        else:
            counted += 1
            number = inc.get("number") or counted
            label = str(number)
        out.append({**inc, "number": number, "label": label,
                    "duration_s": inc["t_end"] - inc["t_start"] + period_s,
                    "peak_ratio": None if top is None else top["peak_ratio"],
                    "peak_ratio_detector": None if top is None else top["detector"]})
    return out


LASTING_WHY = "an unknown payload, a clamp, or a model that no longer fits"


def lasting_text(loads: Sequence[dict[str, Any]]) -> str:
    """The verdict's words for the counted lasting loads, e.g. ``lasting load from 6.5 s
    (to the log's end) on joints j2, j3, up to 14× its threshold: an unknown payload, a
    clamp, or a model that no longer fits``; "" when there is none."""
    parts = []
    for x in loads:
        end = (" (to the log's end)" if x.get("ends_with_log")
               else f" to {x['t_end']:.1f} s")
        force = (f", {force_mark(x)}{approx(x['force_n'])} N at link {x['link']}"
                 if x.get("force_n") is not None and x.get("force_plausible") is not False
                 else "")
        since = (f"from the warm-up's end at {x['t_start']:.1f} s or before"
                 if x.get("on_at_warmup_end") else f"from {x['t_start']:.1f} s")
        parts.append(f"{since}{end} on joints {', '.join(x['joints'])}, "
                     f"up to {approx(x['peak_ratio'])}× its threshold{force}")
    if not parts:
        return ""
    head = "lasting load " if len(parts) == 1 else f"{len(parts)} lasting loads: "
    return head + "; ".join(parts) + f": {LASTING_WHY}"


def truncated_text(duration_s: float) -> str:
    """What a log cut short could not answer (``input.truncated``), in the verdict's words."""
    return (f"The file is truncated: its recording went on after {duration_s:.1f} s, and "
            "what it held after that is not in it, so was not analysed.")


def uncalibrated_none(result: Any) -> str:
    """What an uncalibrated run's "no incident" rests on, in the verdict's words: its
    thresholds come from the log's own motion, so only a contact standing well above it is
    found — and, on a short log, an event filling its few deciding blocks sets its own
    thresholds (:func:`~impactcli.detect.thresholds.self_set_text`; a real UR arm's braking
    read "No incident after warm-up" with the caveat far below)."""
    period = float(result.log.sample_period_s)
    blocks = uncalibrated_blocks(int(result.log.n_samples),
                                 round(float(result.warmup_end_s) / period),
                                 1.0 / period) if period > 0 else 0
    short = self_set_text(blocks)
    return ("Uncalibrated: its thresholds come from this log's own motion, so only a "
            "contact standing well above it would be found" + (f"; {short}" if short else "")
            + " (calibrate on collision-free logs for an audit).")


def incidents_known(result_incidents: int, events: Sequence[dict[str, Any]]) -> bool:
    """Whether the run records incidents: it does when it has any, or when no event of the
    product's detectors exists (then there is none to record). A run made before incidents
    existed has product events and no incident."""
    return result_incidents > 0 or not any(ev["detector"] in PRODUCT_DETECTORS for ev in events)


def peak_torque(inc: dict[str, Any]) -> float:
    """The largest |peak residual| over an incident's joints [N·m]."""
    return max((abs(v) for v in (inc.get("peak_residual") or {}).values()), default=0.0)


def _clock(incs: Sequence[dict[str, Any]]) -> tuple[str, bool] | None:
    """(date, all on that date) when every incident has a UTC time, else None."""
    times = [utc(i.get("t_start_utc")) for i in incs]
    if not times or any(t is None for t in times):
        return None
    days = {t.date() for t in times if t is not None}
    return min(days).isoformat(), len(days) == 1


def _when(inc: dict[str, Any], same_day: bool) -> str:
    t = utc(inc.get("t_start_utc"))
    if t is None:
        return ""
    return f"{t:%H:%M:%S}" if same_day else f"{t:%Y-%m-%d %H:%M:%S}"


def _and(items: Sequence[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def model_made(inc: dict[str, Any]) -> bool:
    """Whether an incident's residual is the model's own torque, not a contact's (its
    force left unstated by :func:`impactcli.detect.incident_builder.beyond_logged`): its
    peak residual is no measure of how hard."""
    return inc.get("force_n") is None and str(inc.get("force_method") or "").startswith(
        BEYOND_LOGGED)


#: How hard, for an incident whose residual is the model's own torque (:func:`model_made`).
MODEL_MADE_TEXT = "no force: part of its residual is the model's own torque"


def _how_hard(group: Sequence[dict[str, Any]], clock: tuple[str, bool] | None) -> str:
    """``~25 N and ~40 N`` (≤ 3 incidents, with clock times), else ``~5 to ~37 N``; the
    peak residual torque where no force is known — not where the residual is the model's
    own torque (:func:`model_made`: no measure of the contact)."""
    with_f = [i for i in group if i.get("force_n") is not None]
    if len(group) <= 3:
        parts = []
        for i in group:
            v = (f"{force_mark(i)}{approx(i['force_n'])} N" if i.get("force_n") is not None
                 else MODEL_MADE_TEXT if model_made(i)
                 else f"~{approx(peak_torque(i))} N·m peak residual")
            when = _when(i, clock[1]) if clock else ""
            parts.append(f"{v} ({when})" if when else v)
        return _and(parts)
    made = sum(model_made(i) for i in group)
    if with_f:
        lo = min(with_f, key=lambda i: i["force_n"])
        hi = max(with_f, key=lambda i: i["force_n"])
        text = (f"{force_mark(lo)}{approx(lo['force_n'])} to "
                f"{force_mark(hi)}{approx(hi['force_n'])} N")
        if len(with_f) < len(group):
            text += f" ({len(group) - len(with_f)} without a force estimate)"
    elif made < len(group):
        ts = [peak_torque(i) for i in group if not model_made(i)]
        text = f"peak residual ~{approx(min(ts))} to ~{approx(max(ts))} N·m"
        if made:
            text += f" ({made} where part of the residual is the model's own torque)"
    else:
        text = f"{MODEL_MADE_TEXT}, in each"
    if clock:
        text += f", {_when(group[0], clock[1])} to {_when(group[-1], clock[1])}"
    return text


def verdict_text(incidents: Sequence[dict[str, Any]], *, known: bool = True,
                 alarms_counted: int = 0,
                 lasting_loads: Sequence[dict[str, Any]] = (),
                 analysed_s: float | None = None, floor: str | None = None,
                 unchecked: Sequence[dict[str, Any]] = (),
                 payload_changes: Sequence[dict[str, Any]] = (),
                 start_load: dict[str, Any] | None = None) -> str:
    """The log's answer in one line, e.g. ``3 incidents: 2 transient on link 2, ~25 N and
    ~40 N; 1 quasi-static on link 1, ~60 N.`` — clock times when the log's clock is an
    epoch; ``No incident after warm-up.`` when none counts; the counted lasting loads
    after the incidents (first when there is no incident), in :func:`lasting_text`'s words.

    Args:
        incidents: the log's incidents (timeline dicts), in time order.
        known: False for a run that records no incidents though its product detectors
            fired (made before incidents existed); ``alarms_counted`` then says how many.
        lasting_loads: the log's lasting loads (timeline dicts).
        analysed_s: the time after warm-up analysed [s] (None: not known); 0 with
            nothing counted is "not judged", not "no incident".
        floor: the run's detection floor in words (:func:`impactcli.detect.floor.
            floor_words`: the lower bound, then the measured one), said after "No incident"
            (what "none" could not have seen).
        unchecked: the joints that moved but were left out of detection (timeline
            ``input.joints_left_out`` items with ``travel_rad``), named at the end.
        payload_changes: the timeline's ``payload_changes``: said, not counted.
        start_load: the timeline's ``input.payload``: when the load the log starts with
            could not be weighed (verdict ``unsupported``) and something counts, said: its
            incidents and lasting loads may be that load's (a trial's 3 kg start on the
            heavy arm read as an 86 N quasi-static contact).
    """
    weighed = (start_load or {}).get("verdict") != "unsupported" or not (
        any(counts_as_contact(i) for i in incidents)
        or any(not x.get("in_warmup") for x in lasting_loads))
    return _verdict(incidents, known, alarms_counted, lasting_loads, analysed_s, floor,
                    payload_changes) + ("" if weighed else (
        " The load the log started with could not be weighed (input.payload): its incidents "
        "and lasting loads may be that load's, not contacts.")) + (
        "" if not unchecked else " Not checked, though they moved: " + "; ".join(
            f"{x['name']} ({x['travel_rad']:.2g} rad; {x['reason']})" for x in unchecked)
        + ".")


def _verdict(incidents: Sequence[dict[str, Any]], known: bool, alarms_counted: int,
             lasting_loads: Sequence[dict[str, Any]], analysed_s: float | None,
             floor: str | None, payload_changes: Sequence[dict[str, Any]] = ()) -> str:
    """:func:`verdict_text` but the unchecked joints."""
    if not known:
        s = "" if alarms_counted == 1 else "s"
        return (f"{alarms_counted} alarm{s} of the product's detectors after warm-up; this "
                "run records no incidents (made before incidents existed), so which link, "
                "how hard and what kind are not known.")
    counted = [i for i in incidents if counts_as_contact(i)]
    warm = sum(1 for i in incidents if i.get("in_warmup"))
    marked = sum(1 for i in incidents if not i.get("in_warmup") and i.get("data_defect"))
    tail = "".join([f" (+{warm} in the warm-up, not counted)" if warm else "",
                    f" (+{marked} at a data defect — a time gap or a position jump — not "
                    "counted: the residual there shows the defect, not a force)"
                    if marked else "",
                    f" ({payload})" if (payload := payload_text(payload_changes)) else ""])
    loads = lasting_text([x for x in lasting_loads if not x.get("in_warmup")])
    if not counted and analysed_s is not None and analysed_s <= 0.0:
        return ("Not judged: the adaptive detector's warm-up covers the whole log, so no "
                f"time after warm-up was analysed{tail}.")
    if not counted:
        if loads:
            return f"{loads[0].upper()}{loads[1:]}; no incident after warm-up{tail}."
        return f"No incident after warm-up{tail}" + (f"; {floor}." if floor else ".")
    clock = _clock(counted)
    # one group per kind and link; "link 5 or 6" (the residuals cannot tell) is its own
    Group = tuple[str, int | None, tuple[int, ...]]
    groups: dict[Group, list[dict[str, Any]]] = {}
    for i in counted:
        others = tuple(c for c in i.get("link_candidates") or () if c != i.get("link"))
        groups.setdefault((i.get("contact") or "unknown", i.get("link"), others),
                          []).append(i)

    def order(kv: tuple[Group, list[dict[str, Any]]]) -> tuple[Any, ...]:
        (kind, link, cands), items = kv
        rank = CONTACT_ORDER.index(kind) if kind in CONTACT_ORDER else len(CONTACT_ORDER)
        return (-len(items), rank, link if link is not None else 10**6, cands)

    parts = []
    for (kind, link, cands), items in sorted(groups.items(), key=order):
        what = (f"{len(items)} of unknown kind (running to the log's end: how long it "
                "pressed cannot be seen, nor whether it is a contact or the recording's "
                "end)" if kind == "unknown"
                else f"{len(items)} {CONTACT_TEXT.get(kind, kind)}")
        where = "on " + link_words(link, cands, unknown="a link the residuals cannot say")
        parts.append(f"{what} {where}, {_how_hard(items, clock)}")
    n = len(counted)
    head = f"{n} incident{'s' if n != 1 else ''}"
    if clock:
        head += f" on {clock[0]} (UTC)" if clock[1] else " (UTC)"
    also = f"; and a {loads}" if loads.startswith("lasting load ") else (
        f"; and {loads}" if loads else "")
    off = [i for i in counted if scale_untrusted(i)]
    bad = sum(1 for i in counted if i.get("force_plausible") is False and i not in off)
    units = ("" if not bad else
             f" {'One estimated force is' if bad == 1 else f'{bad} estimated forces are'}"
             " beyond what the arm can exert: positions in degrees? a wrong gear ratio or "
             "torque constant?") + ("" if not off else
                                    f" No force here can be trusted: {off[0]['force_check']}.")
    under = sum(1 for i in counted if i.get("unseen_load_kg") is not None)
    unseen = ("" if not under else
              f" {'It' if n == 1 else ('All' if under == n else f'{under} of them')} began "
              "while the arm carried a load no calibration log carried: the false-alarm "
              "rate there was not measured, so how many are contacts is not known.")
    return (f"{head}: {'; '.join(parts)}{tail}{also}.{units}{unseen}{_maybe_not(counted)}"
            f"{_held(counted)}")


def _maybe_not(counted: Sequence[dict[str, Any]]) -> str:
    """The verdict's words for the counted incidents the run marked as maybe no new
    contact — in an earlier incident's aftermath (the arm not settled) or just after a
    lasting load ended (that load again): still counted, the residuals cannot tell; ""
    when none. A trial read a verdict of 8 incidents for 4 pushes whose timeline marked
    3 of them so."""
    after = sum(1 for i in counted if i.get("aftermath"))
    close = sum(1 for i in counted if i.get("close_behind"))
    again = sum(1 for i in counted if i.get("resumes_load"))
    data = sum(1 for i in counted if i.get("velocity_disagrees"))
    said = ([f"{after} began in an earlier incident's aftermath, the arm not settled (maybe "
             "its ringing)"] if after else []) + (
        [f"{close} close behind an earlier, stronger one, within the detectors' settling time "
         "(maybe its ringing)"] if close else []) + (
        [f"{again} just after a lasting load ended (maybe that load again)"] if again else []
    ) + ([f"{data} where the log's velocity and positions tell two motions (maybe the "
          "data's)"] if data else [])
    if not said:
        return ""
    return (" Counted, though maybe no new contact: " + " and ".join(said) + ".")


def _held(counted: Sequence[dict[str, Any]]) -> str:
    """The verdict's words for the counted incidents whose alarm ended a load held before
    it (``held_before``): dated and typed by the release, the contact began earlier; ""
    when none."""
    held = [i["held_before"] for i in counted if i.get("held_before")]
    if not held:
        return ""
    since = ", ".join(f"{h['t_start']:.1f} s" for h in held)
    return (f" {'One' if len(held) == 1 else len(held)} of them ended a load held since "
            f"before its alarm (from {since}): the contact began then, its time, type and "
            "force are the release's.")


def counts_as_contact(incident: dict[str, Any]) -> bool:
    """Whether a timeline incident is counted: after warm-up, not at a data defect, not a
    payload change."""
    return (not incident.get("in_warmup") and not incident.get("data_defect")
            and not incident.get("payload_change"))


def payload_text(changes: Sequence[dict[str, Any]]) -> str:
    """The verdict's words for the payload changes, e.g. ``2 payload changes (not counted):
    +0.99 kg at 20.092 s, −0.99 kg at 40.024 s``, each not told from a contact saying why
    (:func:`~impactcli.detect.payload_words.press_text`); "" when none."""
    if not changes:
        return ""
    s = "" if len(changes) == 1 else "s"
    return (f"{len(changes)} payload change{s} (a load picked or released, not counted): "
            + ", ".join(f"{c['mass_kg']:+.2g} kg at {c['t_start']:.3f} s"
                        + ("" if (why := press_text(c)) is None else
                           f" (not told from a contact: {why})") for c in changes))


def incident_counts(incidents: Sequence[dict[str, Any]],
                    lasting_loads: Sequence[dict[str, Any]] = ()) -> dict[str, Any]:
    """Counted incidents, in warm-up, per contact type, the largest force [N] (or None),
    and the counted lasting loads."""
    counted = [i for i in incidents if counts_as_contact(i)]
    forces = [i["force_n"] for i in counted if i.get("force_n") is not None]
    by: dict[str, int] = {}
    for i in counted:
        by[i.get("contact") or "unknown"] = by.get(i.get("contact") or "unknown", 0) + 1
    marked = sum(1 for i in incidents if not i.get("in_warmup") and i.get("data_defect"))
    loads = sum(1 for i in incidents if not i.get("in_warmup") and i.get("payload_change"))
    return {"counted": len(counted), "in_warmup": sum(1 for i in incidents if i.get("in_warmup")),
            **({"data_defect": marked} if marked else {}),
            **({"payload_change": loads} if loads else {}),
            "by_contact": by, "max_force_n": max(forces, default=None),
            "lasting_loads": sum(1 for x in lasting_loads if not x.get("in_warmup"))}


# --------------------------------------------------------------------------- HTML


def _torques(inc: dict[str, Any]) -> str:
    pr = inc.get("peak_residual") or {}
    return " · ".join(f"{e(j)} {approx(v)}" for j, v in pr.items()) + " N·m" if pr else "—"


def load_words(change: dict[str, Any], *, since: bool, why: bool) -> str:
    """What a payload change's alarm is instead of a contact force, as the incident table
    and its plot's caption say it: ``a load released from 40.016 s (its weight ~9.9 N), not
    a contact force`` — or ``… not told from a contact`` (``why``: and why,
    :func:`~impactcli.detect.payload_words.press_text`); ``since``: with its onset."""
    verb = "picked" if change["mass_kg"] > 0 else "released"
    onset = f" from {change['t_start']:.3f} s" if since else ""
    press = press_text(change)
    return (f"a load {verb}{onset} (its weight ~{press_force_n(change):.2g} N), "
            + ("not a contact force" if press is None else "not told from a contact"
               + (f": {press}" if why else "")))


def change_of(row: dict[str, Any], changes: Sequence[dict[str, Any]]
               ) -> dict[str, Any] | None:
    """The payload change (the timeline's, 1-based ``payload_change``) a row (or incident)
    is the alarm of, or None."""
    k = row.get("payload_change")
    if not k or not 0 < int(k) <= len(changes):
        return None
    c = changes[int(k) - 1]
    return c if c.get("mass_kg") is not None and c.get("t_start") is not None else None


def incident_table_html(rows: Sequence[dict[str, Any]], anchor: str, plotted: int,
                        settled_s: float | None = None,
                        payload_changes: Sequence[dict[str, Any]] = ()) -> str:
    """The incident list: when, where, how hard, what kind, which detectors, how far above
    threshold; each row links to its plots (the first ``plotted`` incidents have one). Rows
    are named by ``label``: the counted incidents' numbers, ``w1``… in the warm-up; one in
    the warm-up from ``settled_s`` on (its least length, ``warmup.min_s``) is said to be
    unjudged, not the filters settling from the log's start. The alarm of a payload change
    (``payload_changes``: the timeline's) shows the change's mass and onset, not a force."""
    clock = any(r.get("t_start_utc") for r in rows)
    body = []
    for pos, r in enumerate(rows, 1):
        n = r["label"]
        when = f'{r["t_start"]:.3f} s'
        t = utc(r.get("t_start_utc"))
        if clock and t is not None:
            ms = t.microsecond // 1000
            when = f'{t:%Y-%m-%d %H:%M:%S}.{ms:03d} UTC <span class="note">({when})</span>'
        if r.get("in_warmup"):
            when += ' <span class="note">warm-up: not counted</span>'
        elif r.get("data_defect"):
            d = r["data_defect"]
            when += (f' <span class="bad">at a data defect (a {e(d["kind"])} at '
                     f'{d["t_start"]:.3f} s): not counted</span>')
        elif r.get("payload_change"):
            when += (f' <span class="note">payload change P{r["payload_change"]}: not '
                     "counted</span>")
        if r.get("payload_test"):
            when += f' <span class="note">{e(r["payload_test"])}</span>'
        if (ringing := ringing_text(r)) is not None:
            when += f' <span class="note">{e(ringing)}</span>'
        if r.get("resumes_load"):
            when += f' <span class="note">{e(r["resumes_load"]["text"])}</span>'
        if r.get("load_motion"):
            when += f' <span class="note">{e(r["load_motion"]["text"])}</span>'
        if (chained := chained_text(float(r.get("t_end", r["t_start"])) - r["t_start"])):
            when += f' <span class="bad">{e(chained)}</span>'
        force = (f'<b>{force_mark(r)}{approx(r["force_n"])} N</b>' if r.get("force_n") is not None
                 else '<span class="muted">no force estimate</span>')
        change = change_of(r, payload_changes)
        if change is not None:  # a load, not a contact: its mass, not the alarm's "force"
            force = (f'<b>{change["mass_kg"]:+.3g} kg</b> <span class="note">'
                     f'{e(load_words(change, since=True, why=True))}</span>')
        if r.get("force_n") is None and str(r.get("force_method") or "").startswith(
                FORCE_NOT_STATED):  # why not: the physics checks left it unstated
            force += f' <span class="note">{e(r["force_method"])}</span>'
        if r.get("in_warmup") and settled_s is not None and r["t_start"] >= settled_s:
            force += (' <span class="bad">in a warm-up that ran on past its least '
                      f"{settled_s:g} s (the evaluator had not settled): not judged — it may "
                      "be a contact</span>")
        elif r.get("in_warmup") and r.get("force_n") is not None:  # the filters starting
            force += (' <span class="note">in the warm-up: it may be the filters settling '
                      "from the log's start, not a contact</span>")
        if r.get("force_plausible") is False:
            word = "not trusted" if scale_untrusted(r) else "implausible"
            force += (f' <span class="bad">{word}: '
                      f'{e(r.get("force_check") or "beyond what the arm can exert")}</span>')
        words = link_words(r.get("link"), r.get("link_candidates"))
        link = e(words) + (' <span class="note">(the residuals cannot tell which)</span>'
                           if " or " in words else "")
        ratio = ("—" if r.get("peak_ratio") is None else
                 f'{r["peak_ratio"]:.1f}× <span class="note">{e(r["peak_ratio_detector"])}</span>')
        if r.get("peak_ratio") is not None and str(r.get("payload_test") or "").startswith(
                "a contact beside payload change"):  # its events hold the load's step
            ratio += ' <span class="note">the whole alarm&#x27;s, the load&#x27;s step in it</span>'

        kind = ("—" if change is not None else
                e(CONTACT_TEXT.get(r.get("contact") or "unknown", r.get("contact"))))
        plot = f'<a href="#{anchor}-inc{n}">plot</a>' if pos <= plotted else ""
        cls = (' class="warmup"' if r.get("in_warmup") or r.get("data_defect")
               or r.get("payload_change") else "")
        body.append(
            f'<tr{cls} id="{anchor}-row{n}"><td class="num">{n}</td><td class="num">{when}</td>'
            f'<td class="num">{r["duration_s"]:.2f}</td><td><b>{link}</b></td>'
            f'<td>{force} <span class="small">({_torques(r)})</span></td>'
            f"<td>{kind}</td>"
            f'<td>{e(", ".join(r.get("detectors") or []))}</td><td class="num">{ratio}</td>'
            f"<td>{plot}</td></tr>")
    methods: dict[str, list[int]] = {}
    for pos, r in enumerate(rows):
        methods.setdefault(r.get("force_method") or "—", []).append(pos)
    labels = [str(r["label"]) for r in rows]
    notes = "".join(
        f"<li>{e(m)} (incident{'s' if len(ps) > 1 else ''} {e(_ranges(ps, labels))})</li>"
        for m, ps in methods.items())
    return (
        f'<div class="wide"><table class="incidents" id="{anchor}-incidents"><thead><tr>'
        '<th class="num">#</th><th class="num">first alarm (since log start)</th>'
        '<th class="num">lasting [s]</th><th>where</th><th>how hard (peak)</th><th>kind</th>'
        '<th>detectors (the first to fire first)</th><th class="num">peak / threshold</th><th></th>'
        f'</tr></thead>{"".join(body)}</table></div>'
        '<div class="small muted">When: the incident\'s first alarm; the contact began '
        "before it, by the detectors' delay (`evaluate` measures it against labels). "
        "How hard: the force at the end of the link, where the "
        "contact point is assumed (a contact nearer the joint is usually under-estimated, "
        "on link 1 by the lever-arm ratio); in brackets the peak residual torque of each "
        "joint that fired. "
        + (f"{e(AT_LEAST_TEXT)}. " if any(r.get("force_at_least") for r in rows) else "")
        + f'<ul class="tight">{notes}</ul></div>')


def _carrying(change: dict[str, Any]) -> str:
    from ...detect.payload_words import carrying_text  # the one wording, imported when used

    return carrying_text(change)


def _tested(change: dict[str, Any]) -> str:
    from ...detect.payload_words import tested_text  # the one wording, imported when used

    return tested_text(change)


def payload_table_html(changes: Sequence[dict[str, Any]], anchor: str) -> str:
    """The payload changes (docs/method.md §5c): when, the mass change, its confidence and
    when it was classified; "" when none."""
    if not changes:
        return ""
    body = "".join(
        f'<tr id="{anchor}-payload{k}"><td class="num">P{k}</td>'
        f'<td class="num">{c["t_start"]:.3f} s</td><td class="num"><b>{c["mass_kg"]:+.3g} kg'
        f'</b> (s.e. ≥ {c["mass_se_kg"]:.2g})</td><td>{e(_tested(c))}</td>'
        f'<td class="num">{c["t_classified"]:.3f} s</td>'
        f'<td class="num">{e(_carrying(c))}</td></tr>'
        for k, c in enumerate(changes, 1))
    return (
        f'<div class="wide"><table class="incidents" id="{anchor}-payloads"><thead><tr>'
        '<th class="num">#</th><th class="num">payload change at</th><th class="num">mass'
        '</th><th>a mass, not a press?</th><th class="num">classified at</th>'
        f'<th class="num">load then</th></tr></thead>{body}</table></div>'
        '<div class="small muted">A payload change is a step in the residual that behaves as '
        "a mass at the flange over the poses that follow it: a load picked or released. It "
        "is not an incident and fails no gate (one not told from a press: the gates could "
        "not judge it, exit 5); from its classification on, the residual "
        "carries the new load. Loads are stated beyond the model's own. A mass keeps its "
        "weight as the arm moves (steady) and carries inertia; a press that builds up is not "
        "steady, and a steady press along gravity has no inertia — where the motion is too "
        "slow for inertia to show, the two are not told apart. The standard error counts the "
        "window's samples as independent: a lower bound.</div>")


def lasting_table_html(loads: Sequence[dict[str, Any]], anchor: str) -> str:
    """The lasting loads (alarms of 10 s or more, each a finding of its own): when, which
    detector on which joints, how far above threshold, where and how hard; "" when none."""
    if not loads:
        return ""
    body = []
    for k, x in enumerate(loads, 1):
        end = "the log's end" if x.get("ends_with_log") else f'{x["t_end"]:.3f} s'
        warm = (' <span class="note">warm-up: not counted</span>' if x.get("in_warmup")
                else ' <span class="note">on already when the warm-up ended: it began then '
                'or before</span>' if x.get("on_at_warmup_end") else "")
        link = f'link {x["link"]}' if x.get("link") is not None else "link unknown"
        force = (f'{force_mark(x)}{approx(x["force_n"])} N' if x.get("force_n") is not None
                 else '<span class="muted">no force estimate</span>')
        if x.get("force_plausible") is False:
            force += (' <span class="bad">implausible: '
                      f'{e(x.get("force_check") or "beyond what the arm can exert")}</span>')
        cls = ' class="warmup"' if x.get("in_warmup") else ""
        test = (f' <span class="note">{e(x["payload_test"])}</span>' if x.get("payload_test")
                else "")
        body.append(
            f'<tr{cls} id="{anchor}-load{k}"><td class="num">L{k}</td>'
            f'<td class="num">{x["t_start"]:.3f} s to {end}{warm}{test}</td>'
            f'<td>{e(x["detector"])} on {e(", ".join(x["joints"]))}</td>'
            f'<td class="num">{x["peak_ratio"]:.1f}×</td><td><b>{link}</b></td>'
            f"<td>{force}</td></tr>")
    return (
        f'<div class="wide"><table class="incidents" id="{anchor}-lasting"><thead><tr>'
        '<th class="num">#</th><th class="num">lasting load</th><th>detector, joints</th>'
        '<th class="num">peak / threshold</th><th>where</th><th>how hard (peak)</th>'
        f'</tr></thead>{"".join(body)}</table></div>'
        f'<div class="small muted">A lasting load is an alarm of 10 s or more: '
        f"{LASTING_WHY}. It is counted beside the incidents and absorbs none of them, but "
        "while it lasts its detector is already alarming on its joints: a contact then is "
        "seen only by the other detector (what the audit could not see).</div>")


def _ranges(ps: Sequence[int], labels: Sequence[str]) -> str:
    """``1–3, 5`` from sorted row positions, by their labels (runs of consecutive rows)."""
    out: list[str] = []
    start = prev = ps[0]
    for n in [*ps[1:], None]:
        if n is not None and n == prev + 1:
            prev = n
            continue
        out.append(labels[start] if start == prev else f"{labels[start]}–{labels[prev]}")
        if n is not None:
            start = prev = n
    return ", ".join(out)


def fleet_table_html(doc: dict[str, Any]) -> str:
    """The fleet summary: per log its verdict, what could not be seen, calibration, and
    the score against labels when given."""
    with_q = any(r.get("quality") for r in doc["summary"])
    rows = []
    for k, r in enumerate(doc["summary"]):
        sec = doc["logs"][k]
        qs = r.get("quality")
        qcell = "" if not with_q else (
            '<td class="muted">no labels</td>' if not qs else
            f'<td class="num">{qs["detected"]}/{qs["n_contacts"]} hit, '
            f'{qs["false_alarms"]} false-alarm events'
            f'{e(incident_score_text(qs if "as_incidents" in qs else None, qs["n_contacts"]))}'
            '</td>')
        unseen = "; ".join(c["short"] for c in sec.get("could_not_see") or [] if c.get("short"))
        calib = ('<span class="good">yes</span>' if r["calibrated"]
                 else '<span class="bad">no</span>')
        rows.append(
            f'<tr><td class="num">{k + 1}</td><td><a href="#log{k + 1}">{e(r["stem"])}</a><br>'
            f'<code class="small" title="{e(r["sha256"])}">{e(r["sha256"][:12])}…</code></td>'
            f'<td class="verdict-cell">{e(r["verdict"])}</td>'
            f'<td class="small">{e(unseen)}</td><td>{calib}</td>{qcell}</tr>')
    return (
        '<table class="summary" id="fleet-summary"><thead><tr><th class="num">#</th>'
        "<th>log / sha256 (start)</th><th>verdict</th><th>what the audit could not see</th>"
        "<th>calibrated</th>" + ("<th>vs labels (product)</th>" if with_q else "")
        + f"</tr></thead>{''.join(rows)}</table>")


def fleet_details_html(doc: dict[str, Any]) -> str:
    """The fleet's per-detector numbers (events, worst false-alarm margin), collapsed."""
    rows = []
    for k, r in enumerate(doc["summary"]):
        ev = r["events"]
        cells = "".join(
            f'<td class="num">{ev[d]["events"]}'
            + (f' <span class="muted small">(+{ev[d]["in_warmup"]} w-u)</span>'
               if ev[d]["in_warmup"] else "") + "</td>" for d in ev)
        wj = doc["logs"][k]["false_alarm_margin"]["worst"]
        worst = "".join(ratio_cell(r["worst_margin"].get(d), (wj.get(d) or {}).get("joint"))
                        for d in PRODUCT_DETECTORS)
        ref = (e(r["reference_source"]) if r["reference_source"] == "reference"
               else f'<span class="warn">{e(r["reference_source"])}</span>')
        rows.append(
            f'<tr><td class="num">{k + 1}</td><td>{e(r["stem"])}</td>'
            f'<td class="num">{r["duration_s"]:.1f}</td><td class="num">{r["sample_rate_hz"]:.0f}'
            f'</td><td class="num">{r["n_joints"]}</td>{cells}<td>{ref}</td>{worst}</tr>')
    dets = list(doc["summary"][0]["events"]) if doc["summary"] else []
    head = "".join(f'<th class="num">{e(d)}</th>' for d in dets)
    whead = "".join(f'<th class="num">{e(d)}</th>' for d in PRODUCT_DETECTORS)
    return (
        "<details><summary>Per detector: events and worst false-alarm margin per log"
        '</summary><table class="summary"><tr><th rowspan="2" class="num">#</th>'
        '<th rowspan="2">log</th><th rowspan="2" class="num">duration [s]</th>'
        '<th rowspan="2" class="num">rate [Hz]</th><th rowspan="2" class="num">joints</th>'
        f'<th colspan="{len(dets)}">events after warm-up (+ in warm-up)</th>'
        '<th rowspan="2">reference</th>'
        f'<th colspan="{len(PRODUCT_DETECTORS)}">worst false-alarm margin</th></tr>'
        f"<tr>{head}{whead}</tr>{''.join(rows)}</table></details>")
