"""What the audit could not see, per log: the warm-up, gaps in the log's clock, joints left
out of detection, the run's detection floor and the smallest force each link's
static-loading thresholds catch at one posture, and what an older timeline cannot tell.

Each item is ``{"code", "short", "text", "data"}``: ``short`` for the fleet table, ``text``
as printed, ``data`` the numbers behind it.

**Smallest caught force** (:func:`impactcli.detect.force.smallest_caught_force`), with
planar kinematics: for link i, the static force at the end of link i, in the direction that
turns joint i most (normal to the link), that just reaches joint i's static-loading
threshold: vL_i / (lever arm of joint i to the end of link i); and the smallest force that
reaches the threshold of any joint 1..i. Evaluated at the median posture after warm-up.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...config import settings_changed
from ...detect.envelope import outside_share_text, posture_text
from ...detect.floor import floor_words
from ...detect.force import planar_jacobian, smallest_caught_force
from ...detect.incidents import blind_s, blind_text, defect_blind_words, floor_apart
from ...types import DetectionResult
from .common import approx, e, share
from .samples import Samples

#: At most this many gaps are listed in the JSON.
MAX_GAPS_LISTED = 50


def chain_of(result: DetectionResult) -> tuple[tuple[str, ...], dict[str, Any] | None]:
    """The robot's joint chain (base first) and its kinematics, from the robot description
    given to the run, else the one the model records (as
    :func:`impactcli.detect.incident_builder.robot_chain` reads them, whose link numbers
    the incidents carry); the analysed joints without kinematics when neither is known."""
    desc = result.robot or (result.model or {}).get("robot")
    joints = result.log.joint_names
    if isinstance(desc, dict) and desc.get("joints"):
        inverse = {v: k for k, v in dict(desc.get("joint_map") or {}).items()}
        names = tuple(inverse.get(str(j["name"]), str(j["name"])) for j in desc["joints"])
        if set(joints) <= set(names):
            kin = desc.get("kinematics")
            return names, kin if isinstance(kin, dict) else None
    return tuple(joints), None


def _warmup(result: DetectionResult, incidents: list[dict[str, Any]]) -> dict[str, Any]:
    w = result.warmup_end_s
    n = sum(1 for i in incidents if i.get("in_warmup"))
    per = result.warmup_per_joint_s or {}
    text = (f"Warm-up: the first {w:.3f} s (latest over joints{share(w, result.log.duration_s)})"
            " are the adaptive estimator's convergence; a contact then may go unseen. "
            + (f"{n} incident(s) started in it: listed, not counted." if n
               else "No incident started in it."))
    return {"code": "warmup", "short": f"warm-up to {w:.1f} s", "text": text,
            "data": {"end_s": w, "per_joint_s": dict(per), "incidents_in_warmup": n,
                     "fraction": w / result.log.duration_s if result.log.duration_s else None}}


def _gaps(samples: Samples) -> dict[str, Any]:
    at, lengths = samples.gaps()
    items = [{"t_s": a, "length_s": x} for a, x in zip(at, lengths, strict=True)]
    if not items:
        return {"code": "gaps", "short": "no gap", "data": {"n": 0, "total_s": 0.0, "items": []},
                "text": "Gaps: none — the log's clock has no step much longer than its period."}
    total = float(np.sum(lengths))
    big = max(items, key=lambda x: x["length_s"])
    return {"code": "gaps", "short": f"{len(items)} gap(s), {total:.2g} s",
            "data": {"n": len(items), "total_s": total, "longest_s": big["length_s"],
                     "items": items[:MAX_GAPS_LISTED]},
            "text": (f"Gaps: {len(items)} in the log's clock, {total:.3g} s in all (the longest "
                     f"{big['length_s']:.3g} s at {big['t_s']:.3f} s): nothing was measured "
                     "there, so a contact then was not seen.")}


def _cut(result: DetectionResult) -> list[dict[str, Any]]:
    """The end of a recording the file does not hold (a truncated MCAP or CSV), else nothing."""
    if not result.log.source.truncated:
        return []
    end = result.log.duration_s
    return [{"code": "truncated", "short": f"file cut at {end:.1f} s",
             "data": {"analysed_to_s": end},
             "text": (f"Truncated: the file's records end early, at {end:.3f} s of the "
                      "recording; what was recorded after that is not in the file, so a "
                      "contact then was not seen (and the length of what is missing is not "
                      "known).")}]


def _defects(result: DetectionResult) -> list[dict[str, Any]]:
    """The time after the log's data defects where an alarm was taken for a defect's (not
    counted: a contact starting there was missed), else nothing."""
    dd = result.data_defects or {}
    if (words := defect_blind_words(dd)) is None:
        return []
    n = int(dd["gaps"]) + int(dd["jumps"])
    return [{"code": "data-defects",
             "short": f"{dd['adaptive_blind_s']:.2g} s at data defects",
             "data": {k: dd[k] for k in ("gaps", "jumps", "settle_s", "blind_s",
                                         "adaptive_settle_s", "adaptive_blind_s")},
             "text": (f"Data defects: {n} (gaps in the clock, jumps of the positions no "
                      f"motion explains); {words}.")}]


def _load_motion(incidents: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The counted incidents that came while the arm carried a calibration log's load on
    motion no calibration log with that load covered (``load_motion``), else nothing."""
    there = [i for i in incidents if i.get("load_motion") and i.get("number")]
    if not there:
        return []
    logs = sorted({str(i["load_motion"]["log"]) for i in there})
    return [{"code": "load-motion", "short": f"{len(there)} under a load, unlike motion",
             "data": {"incidents": len(there), "logs": logs},
             "text": (f"A load on unlike motion: {len(there)} counted incident(s) came while "
                      f"the arm carried a calibration log's load ({'; '.join(logs)}) on "
                      "motion no calibration log with that load covered; the thresholds' "
                      "false-alarm rate was measured for that load on those logs' motion "
                      "only, so how many of them are contacts is not known.")}]


def _left_out(result: DetectionResult, chain: tuple[str, ...]) -> dict[str, Any]:
    items = [dict(x) for x in result.joints_left_out]
    if not items:
        return {"code": "joints-left-out", "short": "all joints analysed", "data": {"items": []},
                "text": "Joints left out of detection: none — every logged joint was analysed."}
    desc = "; ".join(
        f"{x.get('name')}" + (f" (link {chain.index(x['name']) + 1})" if x.get("name") in chain
                              else "") + f": {x.get('reason')}" for x in items)
    return {"code": "joints-left-out", "short": f"{len(items)} joint(s) left out",
            "data": {"items": items},
            "text": (f"Joints left out of detection: {desc}. A contact is seen only through "
                     "the joints analysed; links keep their numbers.")}


def _smallest_force(result: DetectionResult, chain: tuple[str, ...],
                    kin: dict[str, Any] | None, samples: Samples) -> dict[str, Any]:
    log = result.log
    vl_nm = {j: result.thresholds.get(j, {}).get("vL") for j in log.joint_names}
    torques = ", ".join(f"{j} {approx(v)} N·m" for j, v in vl_nm.items() if v is not None)
    data: dict[str, Any] = {"kinematics": (kin or {}).get("type"), "vL_nm": vl_nm}
    # the run's detection floor, as detect prints it (over the whole log, both detectors)
    floor = floor_words(result.detection_floor)
    loads = [x.to_dict() for x in result.lasting_loads]
    blind = blind_s(loads)  # the floor holds outside
    words, all_held = floor_apart(loads, result.log.duration_s - result.warmup_end_s)
    apart = (f", outside the {blind:.1f} s a lasting load held its detector alarming (above)"
             if blind > 0 else "")
    said = ("" if floor is None else
            f"Detection floor: not stated — {words}. " if all_held else
            f"Detection floor (as detect states it, over the log after warm-up{apart}): "
            f"{floor}. ")
    if not kin or kin.get("type") != "planar" or not kin.get("link_lengths"):
        why = ("no kinematics are known" if not kin else
               f"the report computes it for planar arms only (this robot: {kin.get('type')})")
        short = (_measured_short(result.detection_floor)
                 or ("no force floor: no kinematics" if not kin else
                     f"no force floor for {kin.get('type')} kinematics"))
        return {"code": "smallest-force", "short": short, "data": {**data, "links": []},
                "text": (f"{said}Static force the static-loading thresholds alone need "
                         f"at one posture: not stated — {why}. The "
                         "static-loading "
                         f"thresholds as torques: {torques}.")}
    medians = samples.posture(result.warmup_end_s)
    q = np.zeros(len(chain))
    for k, j in enumerate(chain):
        if j in log.joint_names:
            q[k] = float(medians[log.joint_names.index(j)])
    vl = [vl_nm.get(j) for j in chain]
    rows = smallest_caught_force(vl, q, planar_jacobian(kin["link_lengths"]))
    for r in rows:
        r["joint"] = chain[r["link"] - 1]
    posture = {j: float(q[k]) for k, j in enumerate(chain)}
    held = [j for j in chain if j not in log.joint_names]
    where = (", ".join(f"{j} {v:.2f} rad" for j, v in posture.items())
             + (f"; {', '.join(held)} held at 0" if held else ""))
    assumption = (
        "a static force at the end of the link (where incident forces are estimated), in the "
        "direction that turns the link's joint most (normal to the link, in the arm's plane), "
        "held until the static-loading low-pass settles; at the median posture after warm-up "
        f"({where})")
    parts = []
    for r in rows:
        if r["own_force_n"] is None:
            parts.append(f"link {r['link']} ({r['joint']}): its joint is not analysed")
            continue
        p = f"link {r['link']} ({r['joint']}) ~{approx(r['own_force_n'])} N"
        if r["any_force_n"] is not None and r["any_force_n"] < 0.95 * r["own_force_n"]:
            p += (f" (joint {chain[r['any_joint'] - 1]} already alarms at "
                  f"~{approx(r['any_force_n'])} N, isolated to an inner link)")
        parts.append(p)
    short = _measured_short(result.detection_floor) or ", ".join(
        f"static push ~{approx(r['own_force_n'])} N on link {r['link']}"
        for r in rows if r["own_force_n"] is not None)
    if all_held:
        short = "no floor: a lasting load throughout"
    elif short and blind > 0:
        short += f" (outside {blind:.0f} s of lasting load)"
    return {"code": "smallest-force", "short": short,
            "data": {**data, "links": rows, "posture_rad": posture,
                     "posture_rule": "median after warm-up", "assumption": assumption},
            "text": (f"{said}Static force the static-loading thresholds alone need at one "
                     f"posture, with the residual at zero: {'; '.join(parts)}. Assumed: "
                     f"{assumption}. Where the residual already stands near its threshold "
                     "less is needed; a contact nearer the joint needs more (force × distance "
                     "to the joint = vL), and so does one shorter than the low-pass takes to "
                     "settle; a short impact may also trip the adaptive detector, whose "
                     "threshold follows the motion.")}


def _older(origin: dict[str, Any] | None, known: bool) -> list[dict[str, Any]]:
    out = []
    if origin and origin.get("timeline_schema_version") == "1.0":
        by = origin.get("recorded_by") or "an older impactcli"
        out.append({"code": "older-timeline", "short": "timeline 1.0",
                    "data": dict(origin),
                    "text": (f"This log came as a timeline of schema 1.0 "
                             f"({origin.get('timeline')}, "
                             f"written by {by}): that file records no incidents, no residual "
                             "generator per joint and no joints left out of detection. "
                             "What this report shows of them comes from re-running detection "
                             "now on the same log (its sha256 checked).")})
    if not known:
        out.append({"code": "no-incidents", "short": "no incidents recorded", "data": {},
                    "text": ("This run records events per detector but no incidents (it was "
                             "made before incidents existed): which link a contact touched, how "
                             "hard and of what kind cannot be told; the alarms are listed per "
                             "detector below.")})
    return out


def _envelope(result: DetectionResult, incidents: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The motion the thresholds' false-alarm rate was not measured on: the share of the log
    outside the calibration's motion envelope (:mod:`impactcli.detect.envelope`); nothing
    when the config recorded no envelope."""
    env = result.motion_envelope
    if env is None:
        return []
    analysed = result.log.duration_s + result.log.sample_period_s - result.warmup_end_s
    if analysed <= 0.0:
        return [{"code": "motion-envelope", "short": "nothing analysed after warm-up",
                 "data": dict(env),
                 "text": ("The warm-up covers the whole log: no time after it was analysed, "
                          "so neither the motion envelope nor the thresholds' stated "
                          "false-alarm rate says anything of this log.")}]
    posture = env.get("posture_outside") or {}
    poses = f"; but {posture_text(posture)}" if posture else ""  # against "inside"
    if not env.get("outside"):
        calibration = result.config.get("calibration") or {}
        rated = (bool(calibration.get("false_alarm_rate"))
                 and not settings_changed(result.config))
        slow_checked = (bool((calibration.get("motion_envelope") or {}).get("slow_dwell_s"))
                        and env.get("source") == "position_ref")
        note = f"; {env['note']}" if env.get("note") else ""
        return [{"code": "motion-envelope",
                 "short": ("inside the calibrated motion, not its poses" if posture
                           else "inside the calibrated motion"),
                 "data": dict(env),
                 "text": ("The log after warm-up moved inside the calibration's motion "
                          "envelope (each joint's velocity and acceleration within the "
                          "ranges calibrated on"
                          + (", and no slow stretch longer" if slow_checked else "")
                          + ")" + note + poses
                          + (": the thresholds' stated false-alarm rate applies."
                             if rated and not posture and not note else "."))}]
    there = sum(1 for i in incidents if i.get("outside_envelope") and i.get("number"))
    return [{"code": "motion-envelope",
             "short": f"{100 * env['share']:.2g} % outside the calibrated motion",
             "data": dict(env),
             "text": (f"{outside_share_text(env)}: the thresholds' stated false-alarm rate "
                      f"was not measured on such motion; {there} counted incident(s) "
                      "touch it "
                      "(marked in the timeline)"
                      + (f"; and {posture_text(posture)}" if posture else "") + ".")}]


def _measured_short(floor: dict[str, Any] | None) -> str:
    """The fleet table's floor: the measured one per link (a 100 ms blow caught at half the
    moments judged, :mod:`impactcli.detect.probe`), "" when none was measured — the
    figure a contact must reach, where the static push at the median posture is the least
    any could (a new user read the static push, about half the measured one, first)."""
    rows = [r for r in ((floor or {}).get("probed") or {}).get("per_link") or ()
            if r.get("median_n") is not None]
    return ("" if not rows else "floor measured " + ", ".join(
        f"~{approx(r['median_n'])} N on link {r['link']}" for r in rows))


def _unseen_load(result: DetectionResult, incidents: list[dict[str, Any]]
                 ) -> list[dict[str, Any]]:
    """The counted incidents and lasting loads that began while the arm carried a load no
    calibration log carried (the timeline's ``unseen_load_kg``): the thresholds'
    false-alarm rate was not measured there; nothing when none did."""
    under = [i for i in incidents if i.get("unseen_load_kg") is not None and i.get("number")]
    lasting = [x for x in result.lasting_loads
               if getattr(x, "unseen_load_kg", None) is not None and not x.in_warmup]
    if not under and not lasting:
        return []
    kg = sorted({round(float(x), 3) for x in [*(i["unseen_load_kg"] for i in under),
                                              *(x.unseen_load_kg for x in lasting)]})
    also = f" and {len(lasting)} lasting load(s)" if lasting else ""
    return [{"code": "unseen-load",
             "short": f"{len(under)} incident(s){also} under a load not calibrated with",
             "data": {"incidents": [int(i["number"]) for i in under],
                      "lasting_loads": len(lasting), "loads_kg": kg},
             "text": (f"{len(under)} counted incident(s){also} began while the arm carried "
                      "a load no calibration log carried ("
                      + ", ".join(f"{m:+.3g}" for m in kg)
                      + " kg beyond the model's): the thresholds' stated false-alarm rate "
                      "was not measured with it, and the rigid model's error under a load "
                      "it was not calibrated with can alarm, so how many of them are "
                      "contacts is not known. Calibrate with a log that carries the load.")}]


def _lasting(result: DetectionResult) -> list[dict[str, Any]]:
    """The stretches where a counted lasting load's detector was already alarming
    (:func:`impactcli.detect.incidents.blind_text`); nothing when there is none."""
    counted = [x.to_dict() for x in result.lasting_loads if not x.in_warmup]
    if not counted:
        return []
    analysed = max(0.0, result.log.duration_s + result.log.sample_period_s
                   - float(result.warmup_end_s))
    text = blind_text(counted, analysed)
    return [{"code": "lasting-load",
             "short": f"{len(counted)} lasting load(s): a detector already alarming",
             "data": {"spans": [{"t_start": x["t_start"], "t_end": x["t_end"],
                                 "detector": x["detector"], "joints": list(x["joints"])}
                                for x in counted]},
             "text": text[:1].upper() + text[1:] + "."}]


def could_not_see(result: DetectionResult, incidents: list[dict[str, Any]], *,
                  samples: Samples, known: bool = True,
                  origin: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """The items of "what the audit could not see" for one log (module docstring);
    ``samples``: where the gaps and the posture are read."""
    chain, kin = chain_of(result)
    return [*_older(origin, known), _warmup(result, incidents), *_cut(result),
            _gaps(samples), *_defects(result), _left_out(result, chain),
            *_envelope(result, incidents), *_load_motion(incidents),
            *_unseen_load(result, incidents), *_lasting(result),
            _smallest_force(result, chain, kin, samples)]


def could_not_see_html(items: list[dict[str, Any]], anchor: str) -> str:
    """The box under the incident list."""
    lis = "".join(f'<li class="unseen-{e(c["code"])}">{e(c["text"])}</li>' for c in items)
    return (f'<div class="unseen" id="{anchor}-unseen"><h3>What the audit could not see</h3>'
            f"<ul>{lis}</ul></div>")
