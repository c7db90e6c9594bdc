"""The sample logs' done criteria (C1–C6), shared by ``tests/test_acceptance.py`` and the
benchmark that prints them, ``tests/benchmarks/sample_quality.py`` (its docstring states the
criteria): where the sample logs and configs are, how a log is replayed and scored, and one
function per criterion returning what decided it."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from impactcli.config import DetectorConfig
from impactcli.logs import read_log
from impactcli.logs.robot_files import read_labels, read_robot
from impactcli.quality.evaluation import Evaluation, evaluate_result
from impactcli.quality.match import PRODUCT
from impactcli.run.calibration import calibrate
from impactcli.run.collect import detect_in_memory
from impactcli.types import DETECTORS, DetectionResult, Labels, RobotDescription, RobotLog

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "sample_logs"
CSV = SAMPLES / "csv"

#: Collision-free logs each committed config is calibrated on: the motion families the
#: contact logs use — triangles (the impacts logs' lead-in), point-to-point moves (their
#: waypoint moves with dwells), slow multi-sines (pushes, clamps). The fast
#: frequency-modulated triangles are left out: no contact log moves like them, and their
#: corner ringing would set the shoulder thresholds (measured in the module's output with
#: ``--on``).
CALIBRATION_LOGS: dict[str, tuple[str, ...]] = {
    "assist_like": ("assist_free_triangle", "assist_free_p2p", "assist_free_multisine"),
    "heavy_geared": ("heavy_free_triangle", "heavy_free_p2p", "heavy_free_multisine"),
}
#: Contact logs → their arm.
CONTACT_LOGS: dict[str, str] = {
    "assist_impacts": "assist_like", "assist_pushes": "assist_like",
    "assist_clamps": "assist_like", "heavy_impacts": "heavy_geared",
}
PAYLOAD_LOG = "assist_payload"
MIN_FORCE_N = 20.0
IMPACT_DELAY_S = 0.080
ROWS: tuple[str, ...] = (*DETECTORS, PRODUCT)


def config_path(arm: str) -> Path:
    """The committed config of ``arm`` (``assist_like`` or ``heavy_geared``)."""
    return SAMPLES / f"{arm}.config.toml"


def log_path(name: str) -> Path:
    return CSV / f"{name}.csv.gz"


def robot_of(name: str) -> RobotDescription:
    return read_robot(CSV / f"{name}.robot.json")


def read(name: str) -> RobotLog:
    """A sample log (CSV copy), read with its robot description."""
    return read_log(log_path(name), robot=robot_of(name))


def labels_of(name: str) -> Labels:
    return read_labels(CSV / f"{name}.labels.json")


def calibrate_on(names: Sequence[str], config: DetectorConfig | None = None,
                 generator: str | None = None) -> DetectorConfig:
    """What ``impactcli calibrate <names> --robot <first's robot> [--config C]
    [--generator G]`` computes."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return calibrate([read(n) for n in names], robot=robot_of(names[0]), config=config,
                         generator=generator)


#: Smallest force the controller-channel criterion C6 asks the product to catch [N].
C6_MIN_FORCE_N = 10.0


@dataclass(frozen=True)
class ReplayedLog(DetectionResult):
    """A detection result with its log in memory (the replayed joints, in ``log``) and the
    (N, J) signals, decisions and ratios its replay handed the writers."""

    signals: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    decisions: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    ratios: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)


def replay(log: RobotLog, **setup: Any) -> ReplayedLog:
    """``log`` replayed in memory (:func:`impactcli.run.collect.detect_in_memory`), with
    its per-sample arrays (``tests/test_acceptance.py`` reads them)."""
    res, sig = detect_in_memory(log, **setup)
    kept = {f.name: getattr(res, f.name) for f in dataclasses.fields(res)}
    return ReplayedLog(**{**kept, "log": log.select(res.log.joint_names)},
                       signals=sig.signals, decisions=sig.decisions, ratios=sig.ratios)


def run(name: str, config: DetectorConfig | None, *, model_from_log: bool = False
        ) -> tuple[DetectionResult, Evaluation]:
    """Replay ``name`` with ``config`` (None: uncalibrated, model from the log) and score it.

    ``model_from_log``: the config's thresholds with a model identified from this very log
    (``detect --config C --model-from-log``).
    """
    log, rob = read(name), robot_of(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = replay(log, config=config, robot=rob, model_from_log=model_from_log)
        ev = evaluate_result(res, labels_of(name))
    return res, ev


# ------------------------------------------------------------------------------- criteria
@dataclass(frozen=True)
class Criterion:
    """One done criterion on one log: passed, and the measurement that decided it."""

    name: str
    log: str
    passed: bool
    detail: str

    def line(self, info: bool = False) -> str:
        """``PASS``/``FAIL`` for a criterion; ``holds``/``does not hold`` for a measurement
        that is not one (``info``)."""
        word = (("holds" if self.passed else "does not hold") if info
                else ("PASS" if self.passed else "FAIL"))
        return f"{word}  {self.name} [{self.log}]: {self.detail}"


def _prev_contact_end(ev: Evaluation, t: float) -> float | None:
    ends = [c.label.end for c in ev.contacts if c.label.end <= t]
    return max(ends) if ends else None


def no_alarm_between_contacts(name: str, ev: Evaluation, detector: str = PRODUCT) -> Criterion:
    """C1: no counted ``detector`` event matching no contact (a false alarm) after warm-up."""
    fa = ev.scores[detector].false_alarm_times
    parts = []
    for t0, t1 in fa:
        prev = _prev_contact_end(ev, t0)
        after = "" if prev is None else f", {t0 - prev:.2f} s after a contact's end"
        parts.append(f"{t0:.3f}–{t1:.3f} s{after}")
    detail = (f"{len(fa)} {detector} alarm(s) between contacts after warm-up "
              f"({ev.warmup_end_s:.2f} s)" + (": " + "; ".join(parts) if parts else ""))
    return Criterion(f"C1 no {detector} alarm between contacts", name, not fa, detail)


def _contacts(ev: Evaluation, kind: str, min_force: float) -> list:
    return [c for c in ev.contacts
            if c.status == "counted" and c.label.kind == kind and c.label.peak_force >= min_force]


def ms_text(x: float | None) -> str:
    return "missed" if x is None else f"{x * 1e3:.0f}"


def impacts_within(name: str, ev: Evaluation, *, min_force: float = MIN_FORCE_N,
                   max_delay_s: float = IMPACT_DELAY_S) -> Criterion:
    """C2: every impact ≥ ``min_force`` caught by the product within ``max_delay_s``."""
    cs = _contacts(ev, "impact", min_force)
    bad = [c for c in cs if c.delay_s[PRODUCT] is None or c.delay_s[PRODUCT] > max_delay_s + 1e-9]
    delays = ", ".join(f"{c.label.peak_force:.1f} N: {ms_text(c.delay_s[PRODUCT])}" for c in cs)
    return Criterion(f"C2 impacts ≥ {min_force:g} N caught by the product within "
                     f"{max_delay_s * 1e3:.0f} ms", name, bool(cs) and not bad,
                     f"{len(cs) - len(bad)}/{len(cs)} (product delays ms — {delays})")


def _while_lasting(c, detector: str) -> bool:
    d = c.delay_s[detector]
    return d is not None and c.label.start + d <= c.label.end + 1e-9


def pushes_while_lasting(name: str, ev: Evaluation, *, min_force: float = MIN_FORCE_N
                         ) -> Criterion:
    """C3: every push ≥ ``min_force`` caught by the product before it ends."""
    cs = _contacts(ev, "push", min_force)
    bad = [c for c in cs if not _while_lasting(c, PRODUCT)]
    det = ", ".join(f"link {c.label.link} {c.label.peak_force:.0f} N: {ms_text(c.delay_s[PRODUCT])}"
                    f"/{(c.label.end - c.label.start) * 1e3:.0f}" for c in cs)
    return Criterion(f"C3 pushes ≥ {min_force:g} N caught while they last", name,
                     bool(cs) and not bad,
                     f"{len(cs) - len(bad)}/{len(cs)} (delay/duration ms — {det})")


def clamps_by_static_loading(name: str, ev: Evaluation, *, min_force: float = MIN_FORCE_N
                             ) -> Criterion:
    """C4: every clamp ≥ ``min_force`` caught by static_loading before it ends."""
    cs = _contacts(ev, "clamp", min_force)
    bad = [c for c in cs if not _while_lasting(c, "static_loading")]
    det = ", ".join(f"{c.label.peak_force:.0f} N: {ms_text(c.delay_s['static_loading'])}"
                    for c in cs)
    return Criterion(f"C4 clamps ≥ {min_force:g} N caught by static_loading", name,
                     bool(cs) and not bad, f"{len(cs) - len(bad)}/{len(cs)} (delays ms — {det})")


def contacts_caught(name: str, ev: Evaluation, *, min_force: float = C6_MIN_FORCE_N
                    ) -> Criterion:
    """C6: every counted contact ≥ ``min_force`` (any kind) caught by the product."""
    cs = [c for c in ev.contacts if c.status == "counted" and c.label.peak_force >= min_force]
    bad = [c for c in cs if c.delay_s[PRODUCT] is None]
    miss = ", ".join(f"{c.label.kind} {c.label.peak_force:.1f} N at {c.label.start:.2f} s"
                     for c in bad)
    return Criterion(f"C6 contacts ≥ {min_force:g} N caught by the product", name,
                     bool(cs) and not bad,
                     f"{len(cs) - len(bad)}/{len(cs)}" + (f" (missed: {miss})" if bad else ""))


def payload_no_false_alarm(label: str, res: DetectionResult, ev: Evaluation) -> Criterion:
    """C5: no product alarm after warm-up on the (collision-free) payload log; also lists
    events that started in warm-up and were still on after it (never counted otherwise)."""
    fa = ev.scores[PRODUCT].false_alarm_times
    lasting = [e for e in res.events if e.in_warmup and e.detector in ("adaptive", "static_loading")
               and e.t_end > res.warmup_end_s]
    per = {d: ev.scores[d].false_alarms for d in DETECTORS}
    detail = (f"model {res.model_source}, {'calibrated' if res.calibrated else 'uncalibrated'}; "
              f"false alarms {per}; product at "
              f"{[round(a, 3) for a, _ in fa]}")
    if lasting:
        detail += "; alarms from warm-up still on after it: " + ", ".join(
            f"{e.detector} {e.t_start:.2f}–{e.t_end:.2f} s" for e in lasting)
    return Criterion(f"C5 payload log: no product alarm ({label})", PAYLOAD_LOG,
                     not fa and not lasting, detail)


def max_ratio_after_warmup(res: DetectionResult) -> dict[str, float]:
    """Per detector, the largest statistic/threshold after warm-up (headroom below 1)."""
    k = int(np.searchsorted(res.log.time_s, res.warmup_end_s))
    return {d: float(np.max(res.ratios[d][k:])) for d in DETECTORS}
