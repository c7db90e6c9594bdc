"""The CI gates of ``detect`` (``--fail-on-detect``, ``--fail-on-force N``), judged from each
finished log's typed findings (:class:`Findings`, carried by its batch outcome).

A log *fails* a gate (exit 1) when it has a counted incident or lasting load after warm-up
(``--fail-on-detect``), or one whose force estimate exceeds N (``--fail-on-force``). A gate
*could not judge* a log (exit 5, when none failed) when its warm-up covers all of it, when
its only incidents start at data defects, when its file is truncated (the recording went on
after the cut), when its warm-up ran on past its least length with alarms there (the
evaluator had not settled: not counted, not judged), or when an incident or lasting load
has no force estimate, or one no one can trust because the log's torque scale is off the
robot description's gravity torque, or when a lasting load under N kept its detector
alarming, blind to a contact on its joints, or when a force under N leaves out a part the
joints do not feel (``--fail-on-force``), or when a payload change
was not told from a contact (its inertia did not show, so a steady press along gravity would
look the same; for ``--fail-on-force`` one whose press would pass N). Each verdict is one
line naming the log and why (docs/formats.md, "Command line"). Payload changes fail no
gate (exit 1); with a gate asked, a log with some gets a line saying how long a contact
would have joined their alarms uncounted (:func:`gate_notes`), the exit code unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..detect.force import AT_LEAST, FORCE_NOT_STATED, force_mark, scale_untrusted
from ..detect.payload_words import press_force_n, press_text
from ..detect.warmup import least_s, past_least
from ..errors import one_line


@dataclass(frozen=True)
class Findings:
    """What the gates judge of one finished log.

    Attributes:
        log_path: the log as given. duration_s, warmup_end_s: [s].
        incidents: the counted incidents (after warm-up, not at a data defect).
        defect_incidents: the incidents after warm-up that start at a data defect.
        lasting_loads: the counted lasting loads (after warm-up).
        payload_changes: the payload changes found (timeline items): not gated.
        truncated: the file ends before its recording did (read up to the cut).
        late_warmup: the incidents in the warm-up from its least length on
            (:func:`impactcli.detect.warmup.past_least`): not counted, not judged.
        least_s: the warm-up's least length [s] (None: not recorded).
        disagreeing: the counted incidents that overlap a stretch where the logged velocity
            and the positions tell two motions (``velocity_disagrees``): their residual may
            be the data's, so neither gate judges them (not in ``incidents``).
    """

    log_path: str
    duration_s: float
    warmup_end_s: float
    incidents: tuple[Any, ...]
    defect_incidents: tuple[Any, ...]
    lasting_loads: tuple[Any, ...]
    payload_changes: tuple[dict[str, Any], ...] = ()
    truncated: bool = False
    late_warmup: tuple[Any, ...] = ()
    least_s: float | None = None
    disagreeing: tuple[Any, ...] = ()

    @classmethod
    def of(cls, log_path: str, result: Any) -> Findings:
        """The findings of ``result`` (a :class:`~impactcli.types.DetectionResult`)."""
        least = least_s(result.config)
        counted = result.counted_incidents()
        data = tuple(i for i in counted if getattr(i, "velocity_disagrees", None))
        return cls(log_path, float(result.log.duration_s), float(result.warmup_end_s),
                   tuple(i for i in counted if i not in data),
                   tuple(result.defect_incidents()), tuple(result.counted_lasting_loads()),
                   tuple(result.payload_changes or ()), bool(result.log.source.truncated),
                   tuple(past_least(result.incidents, least)), least, data)


def shown(log: str) -> str:
    """A log's name as the terminal shows it: its file name (or URL's), on one line."""
    from ..logs.urls import url_name

    return one_line(url_name(log))


def count(n: int, what: str) -> str:
    """``1 incident``, ``3 incidents``."""
    return f"{n} {what}{'s' if n != 1 else ''}"


def judge(findings: Sequence[Findings], *, fail_on_detect: bool,
          fail_on_force: float | None) -> tuple[list[str], list[str]]:
    """(the lines of the logs that fail a gate — exit 1 —, the lines of those a gate could
    not judge — exit 5), in the order of ``findings``, failing ones first per gate."""
    failing: list[str] = []
    unjudged: list[str] = []
    if fail_on_detect:
        failing += [f"impactcli: {shown(f.log_path)}: --fail-on-detect: {_found(f)} after "
                    "warm-up" for f in findings if f.incidents or f.lasting_loads]
        unjudged += [line for f in findings if (line := _not_analysed(f)) is not None]
        unjudged += [line for f in findings if not f.incidents and not f.lasting_loads
                     and (line := _only_defects(f)) is not None]
    if fail_on_force is not None:
        limit = fail_on_force
        failing += [line for f in findings
                    if (line := _over_force(f, limit) or _load_over(f, limit))]
        unjudged += [line for f in findings if (line := _force_unknown(f, limit))]
        unjudged += [line for f in findings if (line := _scale_off(f, limit))]
        unjudged += [line for f in findings if (line := _defect_force(f, limit))]
        unjudged += [line for f in findings if (line := _blind(f, limit))]
        unjudged += [line for f in findings if (line := _at_least(f, limit))]
    if fail_on_detect or fail_on_force is not None:
        gate = "--fail-on-detect" if fail_on_detect else f"--fail-on-force {fail_on_force:g} N"
        unjudged += [line for f in findings
                     if (line := _press(f, gate, None if fail_on_detect else fail_on_force))]
        unjudged += [_cut(f, gate) for f in findings if f.truncated]
        unjudged += [_late(f, gate) for f in findings if f.late_warmup]
        unjudged += [_disagreeing(f, gate) for f in findings if f.disagreeing]
    return failing, unjudged


def _disagreeing(f: Findings, gate: str) -> str:
    """The line of a log with incidents where its velocity and positions tell two motions:
    their residual may be the data's, so the gate could not judge them (the real KUKA
    log's only incident runs into such a stretch; --fail-on-detect failed it, exit 1)."""
    first = f.disagreeing[0]
    n = len(f.disagreeing)
    return (f"impactcli: {shown(f.log_path)}: {gate} could not judge {count(n, 'incident')} "
            f"where the log's velocity and positions tell two motions (the first at "
            f"{first.t_start:.3f} s, the stretch from "
            f"{first.velocity_disagrees['t_start']:.3f} s): the residual there may be the "
            "data's (velocity_disagrees in the timeline); exit 5")


def _late(f: Findings, gate: str) -> str:
    """The line of a log with alarms in a warm-up that ran on past its least length: the
    evaluator had not settled there, so they are neither counted nor judged."""
    first = f.late_warmup[0]
    force = ("" if getattr(first, "force_n", None) is None
             else f", {force_mark(first)}{first.force_n:.3g} N")
    n = len(f.late_warmup)
    return (f"impactcli: {shown(f.log_path)}: {gate} could not judge {count(n, 'alarm')} in "
            f"the warm-up after its least {f.least_s:g} s (the first at {first.t_start:.3f} s"
            f"{force}): the warm-up ran to {f.warmup_end_s:.3f} s "
            f"({100 * f.warmup_end_s / max(f.duration_s, 1e-9):.0f} % of the log) while the "
            "evaluator's prediction error settled, and alarms in it are not counted; exit 5")


def _press(f: Findings, gate: str, limit: float | None) -> str | None:
    """The line of a log with payload changes not told from a contact
    (:func:`~impactcli.detect.payload_words.press_text`: their inertia did not show, so a
    steady press along gravity would look the same; or their mass cannot be trusted) — for
    ``--fail-on-force`` those whose press would pass ``limit`` —, or None: a gate passes no
    clamp as a load it could not weigh (a trial's 20 N clamp on a slow arm was taken for a
    2 kg pick, and both gates passed)."""
    hold = [(k, c, why) for k, c in enumerate(f.payload_changes, 1)
            if (why := press_text(c)) is not None
            and (limit is None or c.get("mass_check") or press_force_n(c) > limit)]
    if not hold:
        return None
    k, c, why = hold[0]
    more = f" (and {count(len(hold) - 1, 'other')})" if len(hold) > 1 else ""
    return (f"impactcli: {shown(f.log_path)}: {gate} could not judge "
            f"{count(len(hold), 'payload change')}: P{k} at {c['t_start']:.3f} s, "
            f"{c['mass_kg']:+.3g} kg: {why}{more}; exit 5")


def _cut(f: Findings, gate: str) -> str:
    """The line of a log whose file ends before its recording did: the gate judged what
    came before the cut only."""
    return (f"impactcli: {shown(f.log_path)}: {gate} could not judge the recording after "
            f"{f.duration_s:.3f} s: the file is truncated (its records end early), so what "
            "was recorded after that is not in it; exit 5")


def gate_notes(findings: Sequence[Findings], *, fail_on_detect: bool,
               fail_on_force: float | None) -> list[str]:
    """With a gate asked, a line per log with payload changes: they fail no gate (a load
    picked or released is normal work), and a contact in their alarms was judged only as
    each one's ``contact_watch`` says — so the exit code does not speak for that time."""
    if not fail_on_detect and fail_on_force is None:
        return []
    gate = "--fail-on-detect" if fail_on_detect else f"--fail-on-force {fail_on_force:g} N"
    out = []
    for f in findings:
        if not f.payload_changes:
            continue
        watched = [c["contact_watch"] for c in f.payload_changes if c.get("contact_watch")]
        blind, end = 0.0, -float("inf")  # the stretches' union: one change's may hold
        for a, b in sorted(tuple(x) for w in watched for x in w["unjudged_s"]):  # the next's
            blind += max(0.0, b - max(a, end))
            end = max(end, b)
        n = len(f.payload_changes)
        their, them = ("their", "them") if n != 1 else ("its", "it")
        told = (f"; a contact in {their} alarms joined {them} uncounted for {blind:.2g} s in "
                f"all, and was told apart in the rest of {their} windows only above "
                f"{max(w['above_times_vl'] for w in watched):g}× the loading thresholds"
                if watched else "")
        out.append(f"impactcli: {shown(f.log_path)}: {gate}: {count(n, 'payload change')} "
                   f"(a load picked or released) {'fails' if n == 1 else 'fail'} no gate"
                   f"{told} (payload_changes in the timeline)")
    return out


def _at_least(f: Findings, limit: float) -> str | None:
    """The line of a log whose incidents or lasting loads under ``limit`` have a force that
    leaves out a part (of a force at the link's end, not seen in the joints' torques:
    ``force_at_least``), or None: --fail-on-force could not judge them (exit 5) — the part
    unseen has no bound (two trials' 30 and 35 N pushes, read ≳24 and ≳24 N, passed a
    limit of 26 and 33 N with exit 0 and a note)."""
    low = [x for x in (*f.incidents, *f.lasting_loads)
           if x.force_n is not None and x.force_n <= limit and x.force_at_least
           and not scale_untrusted(x)]  # those it could not judge
    if not low:
        return None
    forces = sorted(x.force_n for x in low)
    span = (f"{AT_LEAST}{forces[0]:.3g} N" if len(forces) == 1
            else f"{AT_LEAST}{forces[0]:.3g} to {AT_LEAST}{forces[-1]:.3g} N")
    n_inc = sum(1 for x in f.incidents if x in low)
    what = " and ".join(([count(n_inc, "incident")] if n_inc else [])
                        + ([count(len(low) - n_inc, "lasting load")] if len(low) > n_inc
                           else []))
    one = len(low) == 1
    are = "leaves out" if one else "leave out"
    return (f"impactcli: {shown(f.log_path)}: --fail-on-force {limit:g} N could not judge "
            f"the force{'' if one else 's'} of {what} ({span}), which {are} part of the force"
            f": at {'its' if one else 'their'} posture{'' if one else 's'} part of a force at "
            "the link's end turns none of the joints up to it, or too little to be solved "
            "for, so the force may be larger than N (force_method in the timeline); exit 5")


def _found(f: Findings) -> str:
    """"3 incidents and 1 lasting load" of one log (the counted ones)."""
    n, m = len(f.incidents), len(f.lasting_loads)
    return " and ".join(([count(n, "incident")] if n else [])
                        + ([count(m, "lasting load")] if m else []))


def _only_defects(f: Findings) -> str | None:
    """The line of a log whose only incidents start at data defects (--fail-on-detect
    cannot tell whether a contact hides there), or None."""
    if not f.defect_incidents:
        return None
    first = f.defect_incidents[0]
    return (f"impactcli: {shown(f.log_path)}: --fail-on-detect could not judge "
            f"{count(len(f.defect_incidents), 'incident')} at data defects (the first at "
            f"{first.t_start:.3f} s, a {first.data_defect['kind']}): the residual there "
            "shows the defect; exit 5")


def _defect_force(f: Findings, limit: float) -> str | None:
    """The line of a log with incidents at data defects whose force is above ``limit`` or
    unknown (--fail-on-force cannot tell a contact there from the defect), or None."""
    marked = [i for i in f.defect_incidents if i.force_n is None or i.force_n > limit]
    if not marked:
        return None
    first = marked[0]
    force = ("no force" if first.force_n is None
             else f"{force_mark(first)}{first.force_n:.3g} N")
    return (f"impactcli: {shown(f.log_path)}: --fail-on-force {limit:g} N could not "
            f"judge {count(len(marked), 'incident')} at data defects (the first at "
            f"{first.t_start:.3f} s, a {first.data_defect['kind']}, {force}): the residual "
            "there shows the defect; exit 5")


def _not_analysed(f: Findings) -> str | None:
    """The line of a log whose warm-up covers all of it (nothing after warm-up was
    analysed, so --fail-on-detect cannot judge it), or None."""
    if not f.warmup_end_s > f.duration_s:
        return None
    return (f"impactcli: {shown(f.log_path)}: --fail-on-detect could not judge it: "
            f"the adaptive detector's warm-up covers the whole log ({f.duration_s:.3f} s), "
            "so no time after warm-up was analysed (exit 5; a longer log, or one that starts "
            "at rest, is judged)")


def _force_unknown(f: Findings, limit: float) -> str | None:
    """The line of a log with incidents or lasting loads that have no force estimate
    (--fail-on-force cannot judge them), or None."""
    incs = [i for i in f.incidents if i.force_n is None]
    lds = [x for x in f.lasting_loads if x.force_n is None]
    if not incs and not lds:
        return None
    what = ([f"{count(len(incs), 'incident')} (the first at {incs[0].t_start:.3f} s)"]
            if incs else []) + ([count(len(lds), "lasting load")] if lds else [])
    unfit = sum(1 for x in (*incs, *lds) if x.force_method.startswith(FORCE_NOT_STATED))
    why = ("no kinematics — give --robot with a URDF or a named robot — or the link could "
           "not be told" + (f"; for {unfit}, no single force at the link's end gives the "
                            "residuals, or the model's torque passed what the joint "
                            "exerted: force_method in the timeline" if unfit else ""))
    return (f"impactcli: {shown(f.log_path)}: --fail-on-force {limit:g} N could not "
            f"judge {' and '.join(what)}: no force estimate ({why}); exit 5")


def _scale_off(f: Findings, limit: float) -> str | None:
    """The line of a log whose incidents or lasting loads under ``limit`` have a force no
    one can trust (the log's torque scale is off the robot description's gravity torque:
    ``force_check`` begins with :data:`~impactcli.detect.force.OFF_SCALE`), or None: the
    gate cannot pass them."""
    low = [x for x in (*f.incidents, *f.lasting_loads) if x.force_n is not None
           and x.force_n <= limit and scale_untrusted(x)]
    if not low:
        return None
    return (f"impactcli: {shown(f.log_path)}: --fail-on-force {limit:g} N could not judge "
            f"{count(len(low), 'finding')} under the limit (the first at "
            f"{low[0].t_start:.3f} s, {force_mark(low[0])}{low[0].force_n:.3g} N): "
            f"{low[0].force_check}; exit 5")


def _over_force(f: Findings, limit: float) -> str | None:
    """One line naming the log's first incident whose force exceeds ``limit`` (and how many
    do), or None when none does."""
    over = [i for i in f.incidents if i.force_n is not None and i.force_n > limit]
    if not over:
        return None
    inc = over[0]
    link = f"link {inc.link}" if inc.link is not None else "an unknown link"
    more = f" ({len(over)} incidents above it)" if len(over) > 1 else ""
    return (f"impactcli: {shown(f.log_path)}: the incident at {inc.t_start:.3f} s "
            f"on {link}, {force_mark(inc)}{inc.force_n:.3g} N, exceeds --fail-on-force "
            f"{limit:g} N{more}")


def _load_over(f: Findings, limit: float) -> str | None:
    """One line naming the log's first lasting load whose force exceeds ``limit``."""
    def top(x: Any) -> float:  # its peak (a contact inside it, or its motion) is judged
        return max(x.force_n, getattr(x, "peak_force_n", None) or 0.0)

    over = [x for x in f.lasting_loads if x.force_n is not None and top(x) > limit]
    if not over:
        return None
    x = over[0]
    link = f"link {x.link}" if x.link is not None else "an unknown link"
    peak = ("" if top(x) == x.force_n else
            f" over its span and {force_mark(x)}{top(x):.3g} N at its peak")
    return (f"impactcli: {shown(f.log_path)}: the lasting load from "
            f"{x.t_start:.3f} s on {link}, {force_mark(x)}{x.force_n:.3g} N{peak}, exceeds "
            f"--fail-on-force {limit:g} N")


def _blind(f: Findings, limit: float) -> str | None:
    """One line for a log whose lasting loads, none over ``limit``, kept their detector
    alarming on their joints: a contact then raised no event of it there (a push under a
    load held 20–40 s went unseen in a trial), so the gate could not judge that time."""
    loads = [x for x in f.lasting_loads if x.force_n is not None and x.force_n <= limit]
    if not loads or len(loads) < len(f.lasting_loads):  # one over: exit 1; no force: said
        return None
    from ..detect.incidents import blind_text

    return (f"impactcli: {shown(f.log_path)}: --fail-on-force {limit:g} N could not judge "
            f"every contact: {blind_text([x.to_dict() for x in loads])}; exit 5")

