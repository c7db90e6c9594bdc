"""The isolation case shared by ``tests/benchmarks/isolation_quality.py`` (which measures
it among others) and ``tests/test_incidents_truth.py`` (which holds the product to it):
pushes on link 2 at 35 % of its length (:func:`link2_at_35`), with joint 2's thresholds
raised so that its detectors stay silent (:func:`raised`)."""

from __future__ import annotations

from dataclasses import replace

from impactcli.config import DetectorConfig
from impactcli.sim import Scenario, scenario
from impactcli.sim.contacts import Push


def link2_at_35(arm: str) -> Scenario:
    """12 pushes on link 2 at 35 % of its length during frequency-modulated triangles."""
    scale = 1.0 if arm == "assist_like" else 3.0
    ps = tuple(Push(link=2, t0_s=8.0 + 4.0 * k,
                    peak_n=scale * (10.0, 15.0, 20.0, 25.0, 30.0, 40.0)[k % 6],
                    duration_s=(0.03, 0.1, 0.2)[k % 3], point=0.35,
                    direction_deg=-90.0 if k % 2 else 90.0) for k in range(12))
    return replace(scenario("free_fm_triangle", arm, 60.0), pushes=ps)


def raised(cfg: DetectorConfig, joint: str, factor: float) -> DetectorConfig:
    """``cfg`` with ``joint``'s three thresholds times ``factor``."""
    th = cfg.thresholds
    up = {k: {**getattr(th, k), joint: getattr(th, k)[joint] * factor}
          for k in ("v_stat", "v0", "vL")}
    return replace(cfg, thresholds=replace(th, **up))
