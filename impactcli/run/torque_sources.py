"""Which torque source predicts better, when a log carries both (docs/formats.md,
"Torque: .torque or .current").

A joint's ``.torque`` is its torque after the reduction: from a joint torque sensor (link
side, after the motor's friction and the rotor's inertia) or computed by the controller
from the motor (motor side). Its ``.current`` is the motor current, turned into motor-side
torque by the gear ratio and torque constant of the robot description. The rule of which
the tool reads stays the documented one (``.torque`` when present, ``--torque-source``
overrides); this module measures, on the logs given, how well each source is predicted by
the same rigid model held back, so that ``inspect`` and ``calibrate`` can say when the
other source predicts clearly better:

* Each log is read twice, once per source. Where the converted current equals the logged
  torque (within :data:`SAME_FRACTION` of its RMS on every joint) the two are one source
  and nothing is fitted.
* Otherwise the model kind the robot description names (decoupled without kinematics) is
  fitted on each source's rows and judged on the same held-back parts
  (:func:`impactcli.model.selection.named_errors`: leave-one-log-out with two logs or
  more, stretches of one log otherwise).
* Per joint, the other source is **clearly better** when the one-standard-error rule over
  the parts' held-back mean squared errors [N·m²] (absolute: both sources are torques)
  picks it over the source in use and it cuts the held-back RMS error by at least
  :data:`~impactcli.model.selection.MIN_GAIN` (25 %, the least gain a richer model kind
  must also show; :func:`impactcli.model.selection.one_se`, the source in use first):
  better on average is not enough.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ImpactError
from ..types import ReadOptions, RobotDescription, RobotLog

if TYPE_CHECKING:
    from ..model.rows import Rows

#: The converted current and the logged torque are one source when they differ by less
#: than this fraction of the torque's RMS on every joint (a CSV's printed digits).
SAME_FRACTION = 1e-4

SOURCES = ("torque", "current")

#: ``inspect`` reads the log's samples (both sources) only up to this many samples × joints
#: (about 12 minutes of a 7-joint 1 kHz log: 360 MB a read); ``inspect`` itself holds its
#: times only.
INSPECT_MAX_VALUES = 5_000_000


@dataclass(frozen=True)
class SourceComparison:
    """Both sources of the logs judged alike.

    Attributes:
        in_use: the source the verb reads (``torque`` or ``current``); ``other``: the other.
        kind: the model kind fitted on each (None: not fitted — one source, or not judged).
        held_back: how the parts were held back (None when not fitted).
        rms_nm: per joint, (in use, other) held-back RMS error [N·m] (empty when not fitted).
        clearly_better: the joints the other source predicts clearly better.
        same: the converted current is the logged torque (one source).
        reason: why the sources were not judged (None when they were, or are one).
    """

    in_use: str
    other: str
    kind: str | None
    held_back: str | None
    rms_nm: dict[str, tuple[float, float]]
    clearly_better: tuple[str, ...]
    same: bool = False
    reason: str | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (``inspect --json``'s ``torque_sources``)."""
        return {"in_use": self.in_use, "other": self.other, "kind": self.kind,
                "held_back": self.held_back, "same": self.same, "reason": self.reason,
                "joints": {j: {"in_use_rms_nm": a, "other_rms_nm": b,
                               "other_clearly_better": j in self.clearly_better}
                           for j, (a, b) in self.rms_nm.items()}}

    def lines(self) -> list[str]:
        """Lines for the terminal."""
        head = f"torque sources: .torque and .current are both logged; reading .{self.in_use}"
        if self.same:
            return [f"{head}; .current × gear ratio × torque constant equals .torque here "
                    "(one source: nothing to choose)"]
        if self.reason is not None:
            return [f"{head}; not compared: {self.reason}"]
        w = max(5, *(len(j) for j in self.rms_nm))
        out = [f"{head}; the {self.kind} model fitted on each",
               f"  held back: {self.held_back}; rule: the other source is named when it is "
               "better by more than one standard error and by 25 % of the RMS error",
               f"  {'joint':<{w}}  {'.' + self.in_use:>10}  {'.' + self.other:>10}  "
               "[held-back RMS error, N·m]"]
        for j, (a, b) in self.rms_nm.items():
            mark = f"  .{self.other} clearly better" if j in self.clearly_better else ""
            out.append(f"  {j:<{w}}  {a:>10.3g}  {b:>10.3g}{mark}")
        if self.clearly_better:
            out.append(f"  consider --torque-source {self.other} "
                       f"({', '.join(self.clearly_better)})")
        else:
            out.append(f"  .{self.other} predicts no joint clearly better: keep .{self.in_use}")
        return out

    def advice(self) -> str | None:
        """The warning to give when the other source predicts clearly better, else None."""
        if not self.clearly_better:
            return None
        return (f".{self.other} predicts joint(s) {', '.join(self.clearly_better)} clearly "
                f"better than .{self.in_use} held back: consider --torque-source {self.other}")


def inspect_sources(described: dict[str, Any], robot: RobotDescription | None,
                    read_options: ReadOptions) -> SourceComparison | None:
    """What ``inspect`` says of a log's torque sources (``described``: its
    :func:`impactcli.logs.inspect_log`): as :func:`judge_sources`."""
    in_use = described["torque_source"]
    if in_use == "torque" and "current" not in described["signals"]:
        return None
    values = int(described["n_samples"]) * int(described["n_joints"])
    if values > INSPECT_MAX_VALUES:
        return SourceComparison(in_use, SOURCES[1 - SOURCES.index(in_use)], None, None, {}, (),
                                reason=f"the log is too long to compare here ({values:,} "
                                f"samples × joints, over {INSPECT_MAX_VALUES:,}: each source "
                                "is read whole); calibrate compares them on its logs")
    c = compare_torque_sources([described["path"]], robot, read_options, in_use)
    return None if in_use == "current" and c.reason is not None else c


def judge_sources(logs: Sequence[RobotLog], robot: RobotDescription | None,
                  read_options: ReadOptions) -> SourceComparison | None:
    """What ``calibrate`` says of its logs' torque sources: None when there is nothing to
    say — a log without the other source, or (reading ``.current``) logs without
    ``.torque``; else :func:`compare_torque_sources` of their paths."""
    in_use = logs[0].source.torque_source
    if in_use == "torque" and any(lg.current is None for lg in logs):
        return None
    c = compare_torque_sources([lg.source.path for lg in logs], robot, read_options, in_use,
                               read=logs)
    return None if in_use == "current" and c.reason is not None else c


def compare_torque_sources(paths: Sequence[str | Path], robot: RobotDescription | None,
                           read_options: ReadOptions, in_use: str,
                           read: Sequence[RobotLog] | None = None) -> SourceComparison:
    """Both sources of ``paths`` judged alike (module doc). ``in_use``: the source the verb
    reads; ``read``: the logs as the verb read them from it (None: read here). A source
    that cannot be read (a current without gear ratio or torque constant) gives a
    comparison with its ``reason``."""
    other = SOURCES[1 - SOURCES.index(in_use)]
    logs = _read_both(paths, robot, read_options, in_use, read)
    if isinstance(logs, str):
        return SourceComparison(in_use, other, None, None, {}, (), reason=logs)
    if all(_same(x, y) for x, y in zip(logs["torque"], logs["current"], strict=True)):
        return SourceComparison(in_use, other, None, None, {}, (), same=True)
    return _fit_both(logs, robot, [str(p) for p in paths], in_use, other)


def _read_both(paths: Sequence[str | Path], robot: RobotDescription | None,
               read_options: ReadOptions, in_use: str, read: Sequence[RobotLog] | None
               ) -> dict[str, list[RobotLog]] | str:
    """Each source's logs (``read``: the source in use's, as the verb read them), or why
    they cannot be had: a current without its conversion, a read error, a joint one
    source lacks."""
    from ..logs import read_log

    base = {k: v for k, v in read_options.as_dict().items() if k != "torque_source"}
    if robot is None and "channel_map" not in base:  # before any read
        return ("turning .current into torque needs a robot description (--robot) with each "
                "joint's gear_ratio and torque_constant")
    logs: dict[str, list[RobotLog]] = {} if read is None else {in_use: list(read)}
    for s in SOURCES:
        if s in logs:
            continue
        try:
            with warnings.catch_warnings():  # the verb's own read has said them
                warnings.simplefilter("ignore")
                logs[s] = [read_log(p, robot=robot, torque_source=s, **base) for p in paths]
        except ImpactError as e:
            return f"reading .{s}: {e}"
    for x, y in zip(logs["torque"], logs["current"], strict=True):
        if x.joint_names != y.joint_names or x.n_samples != y.n_samples:
            return (f"{x.source.path}: read from .torque and from .current, the log has "
                    f"joints {', '.join(x.joint_names)} and {', '.join(y.joint_names)} "
                    f"({x.n_samples} and {y.n_samples} samples): a joint one source does not "
                    "log")
    return logs


def _fit_both(logs: dict[str, list[RobotLog]], robot: RobotDescription | None,
              names: list[str], in_use: str, other: str) -> SourceComparison:
    """The robot description's model kind fitted on each source and judged on the same
    held-back parts (module doc)."""
    from ..model.identification import default_kind, prepare_rows
    from ..model.identify_options import IdentifyOptions
    from ..model.selection import (
        MIN_GAIN,
        folds_of,
        named_errors,
        one_se,
        payload_errors,
        row_counts,
    )

    kind = default_kind(robot)
    options = IdentifyOptions()
    errors: dict[str, dict[str, dict[str, Any]]] = {}
    rows: dict[str, list[Rows]] = {}
    held: str | None = None
    try:
        with warnings.catch_warnings():  # identification's warnings belong to the fit
            warnings.simplefilter("ignore")
            for s in (in_use, other):
                rows[s] = [prepare_rows(lg, robot, kind, options) for lg in logs[s]]
            # logs with kinematics whose fit takes a payload per log (as calibrate then
            # fits them): so judged — else logs that carry different loads hide each
            # source's error under the one load's
            mine_pl = payload_errors(rows[in_use], names, options)
            other_pl = (payload_errors(rows[other], names, options)
                        if mine_pl is not None and mine_pl["chosen"] else None)
            if mine_pl is not None and other_pl is not None:
                errors = {s: {jn: {"rms_nm": e["per_log_rms_nm"],
                                   "parts_rms_nm": e["parts_per_log_rms_nm"]}
                              for jn, e in pl["joints"].items()}
                          for s, pl in ((in_use, mine_pl), (other, other_pl))}
                held = (f"each log held out in turn, a payload per log (its own weighed on "
                        f"its first {mine_pl['start_s']:g} s)")
            else:
                for s in (in_use, other):
                    errors[s] = dict(zip(rows[s][0].joints,
                                         named_errors(rows[s], names, options), strict=True))
    except ImpactError as e:
        return SourceComparison(in_use, other, kind, None, {}, (), reason=str(e))
    mine = rows[in_use]
    if held is None:
        held = folds_of(row_counts(mine), names, max(r.cv_gap for r in mine))[1]
    rms: dict[str, tuple[float, float]] = {}
    better: list[str] = []
    for jn in mine[0].joints:
        a, b = errors[in_use][jn], errors[other].get(jn)
        if b is None or len(b["parts_rms_nm"]) != len(a["parts_rms_nm"]):
            return SourceComparison(in_use, other, kind, None, {}, (), reason=(
                f"the two sources' fits hold different joints or parts ({jn})"))
        rms[jn] = (a["rms_nm"], b["rms_nm"])
        mse = np.square([a["parts_rms_nm"], b["parts_rms_nm"]])
        if one_se(mse, np.array(rms[jn]), MIN_GAIN)[0] == 1:
            better.append(jn)
    return SourceComparison(in_use, other, kind, held, rms, tuple(better))


def _same(a: RobotLog, b: RobotLog) -> bool:
    """The two reads of one log carry the same torque (:data:`SAME_FRACTION`)."""
    if a.torque.shape != b.torque.shape:
        return False
    scale = np.sqrt(np.mean(a.torque**2, axis=0))
    diff = np.max(np.abs(a.torque - b.torque), axis=0)
    return bool(np.all(diff <= SAME_FRACTION * np.maximum(scale, 1e-12)))
