"""The residual and threshold inputs of a sample log as ``detect`` makes them with its arm's
committed config, for the evaluator's own tests and benchmarks (the replay of
:mod:`impactcli.run.replay` on the whole log as one chunk)."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np

from impactcli.config import AdaptiveConfig, load_config
from impactcli.detect.adaptive import inputs_chunk
from impactcli.errors import ImpactWarning
from impactcli.logs import read_log
from impactcli.model import RigidModel
from impactcli.model.causal import Carry
from impactcli.model.generators import choose_generators
from impactcli.run.replay import Replayer, ReplaySetup, ReplayState, chunk_arrays

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
#: Each sample arm's committed config (by the log's name prefix).
CONFIGS = {"assist": "assist_like.config.toml", "heavy": "heavy_geared.config.toml"}


def replay(name: str, scale_model: float = 1.0, adaptive: AdaptiveConfig | None = None
           ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, AdaptiveConfig]:
    """(r, u, fs, v_stat, cfg) of a sample log as detect makes them with its arm's config,
    every model parameter scaled by ``scale_model``."""
    cfg = load_config(SAMPLES / CONFIGS[name.split("_", maxsplit=1)[0]])
    if adaptive is not None:
        cfg = dataclasses.replace(cfg, adaptive=adaptive)
    model = None
    if cfg.model:
        d = dict(cfg.model)
        d["parameters"] = [{**x, "value": x["value"] * scale_model}
                           for x in d["parameters"]]
        model = RigidModel.from_dict(d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        log = read_log(SAMPLES / "csv" / f"{name}.csv.gz")
        choices = choose_generators(log, cfg.residual.generator,
                                    cfg.residual.generators or None)
        setup = ReplaySetup(log.joint_names, choices, model, cfg, log.sample_rate_hz,
                            log.sample_period_s)
        rp = Replayer(setup, ReplayState.initial(setup))
        try:
            done = rp.feed(None, chunk_arrays(log, log.time_s))
            done += rp.finish()
        finally:
            rp.close()
        u = inputs_chunk(log, log.time_s, log.sample_rate_hz, cfg.adaptive, Carry(), name).u
    r = np.concatenate([out.r for _, out in done])
    v_stat = cfg.thresholds.vector("v_stat", log.joint_names)
    return r, u, log.sample_rate_hz, v_stat, cfg.adaptive
