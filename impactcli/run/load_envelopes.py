"""The motion the calibration logs cover, whole and per load (docs/method.md §5b).

The union of every calibration log's kept motion is the calibration's envelope
(:mod:`impactcli.detect.envelope`): the thresholds' false-alarm rate holds inside it. With
logs that carried different loads, the rate under one load was measured on the motion of
the logs that carried it only, so each such load gets its own envelope
(:mod:`impactcli.detect.load_motion`). Nothing here reads or writes files.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..detect.envelope import SLOW_RAD_S, EnvelopeAccumulator, MotionEnvelope
from ..model import RigidModel

#: A calibration log's load is another than the model's (for its motion envelope) only where
#: its torque in that log reaches this share of some joint's loading threshold: a fit's
#: 2.6 g, 3.7 standard errors from none, turned no joint past 2 % of it; 0.5 kg, 4×. Two
#: logs' loads are alike (one envelope) where the difference of their mass and centre of mass
#: turns none so far (their inertia, which a log's motion determines poorly, is left out: two
#: fits of one 1 kg load differed by a fifth in it).
LOAD_TORQUE_SHARE = 0.1


def union_envelope(replays: Sequence[Any], keeps: Sequence[np.ndarray],
                   joints: tuple[str, ...]) -> MotionEnvelope | None:
    """The motion envelope of every log's kept samples (``replays``: the calibration's
    replays, with ``motion``, ``motion_source``, ``slow_rad_s`` and ``warmup``; its slow
    stretches: of every sample after warm-up, read at the model's slow speed; a log whose
    slow clock was read at another, one replayed without the model, adds its ranges
    only)."""
    sources = {rp.motion_source for rp in replays}
    src = "position_ref" if sources == {"position_ref"} else "position"
    speed = max((rp.slow_rad_s for rp in replays), default=SLOW_RAD_S)
    acc = EnvelopeAccumulator(joints, src, slow_rad_s=speed)
    for rp, keep in zip(replays, keeps, strict=True):
        if rp.motion is not None and rp.motion_source == src:
            slow_from = (rp.warmup.end_index if rp.slow_rad_s == speed
                         else rp.motion.slow.shape[0])
            acc.add(rp.motion, keep, slow_from)
    return acc.finish()


def load_envelopes_of(model: RigidModel | None, replays: Sequence[Any],
                      keeps: Sequence[np.ndarray], joints: tuple[str, ...],
                      v_l: dict[str, float]) -> tuple[dict[str, Any], ...] | None:
    """Per calibration log whose load differs from the model's (:func:`~impactcli.model.
    payload.loaded_logs`) and whose mass and first moments turn some joint, over that log's
    motion, to at least
    :data:`LOAD_TORQUE_SHARE` of its loading threshold (``v_l``): ``{log, mass_kg,
    envelope}``, the motion envelope of the kept samples of every calibration log whose
    load is alike (the difference of their mass and centre of mass turns no joint so far
    over either's motion; that log among them) — the motion the thresholds' rate was
    measured on under that load; None when none does."""
    from ..model.payload import STATIC, calibration_loads, carrying, loaded_logs

    if model is None:
        return None
    floor = np.array([LOAD_TORQUE_SHARE * v_l[j] for j in joints])
    pis = dict(calibration_loads(model, None))
    names = list((model.fit or {})["payloads"]["parameters"]) if pis else []
    static = np.array([nm in STATIC for nm in names])

    def at(log: str) -> list[int]:
        return [k for k, rp in enumerate(replays) if rp.path == log]

    base: dict[int, np.ndarray] = {}  # each log's torque under the model's own load

    def own(k: int, m: Any) -> np.ndarray:
        if k not in base:
            base[k] = model.predict(m.position, m.velocity, m.acceleration)
        return base[k]

    def turns(delta: np.ndarray, ks: list[int]) -> bool:
        heavy = carrying(model, delta)
        return any(bool(np.any(np.max(np.abs(heavy.predict(m.position, m.velocity,
                                                               m.acceleration) - own(k, m)),
                                          axis=0) >= floor))
                   for k in ks if (m := replays[k].motion) is not None)

    out = []
    for e in loaded_logs(model):
        pi = pis.get(e["log"])
        if pi is None or not turns(np.where(static, pi, 0.0), at(e["log"])):
            continue
        ks = [k for f, pf in pis.items()
              if f == e["log"] or not turns(np.where(static, pi - pf, 0.0), at(e["log"]) + at(f))
              for k in at(f)]
        env = union_envelope([replays[k] for k in ks], [keeps[k] for k in ks], joints)
        if env is not None:
            out.append({"log": e["log"], "mass_kg": float(e["values"]["m"]),
                        "envelope": env.to_dict()})
    return tuple(out) or None
