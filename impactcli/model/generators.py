"""Residual generators per joint, including the controller's own channels (formats.md,
"Model and detector config"; method.md §2).

Four generators make the residual r ≈ tau_ext (eq. 8) that every detector evaluates:

* ``inverse_dynamics`` (eq. 7–8) and ``momentum_observer`` (De Luca): the tool's own
  identified rigid model (:mod:`impactcli.model.residual`).
* ``logged_external``: r = the log's ``torque_ext``, the controller's own external-torque
  estimate, as logged (either sign convention: every detector uses magnitudes).
* ``logged_model``: r = tau_hat − tau with tau_hat = (1 + a) τ_m + f_v q' + f_c tanh(q'/v_s)
  + c, where τ_m is the log's ``torque_model`` (the controller's model torque for the
  measured motion) and (a, f_v, f_c, c) is a per-joint *correction* for what that model
  leaves out — a scale error, viscous and Coulomb friction, an offset — identified by a robust
  fit (:func:`impactcli.model.identify.robust_lstsq`) of tau − τ_m on collision-free logs.
  As for ``inverse_dynamics`` (method.md §8) the measured torque, τ_m and the correction's
  regressors all pass through the same causal filter G, so the model side and the measured
  side share one bandwidth; the friction regressors are made from a wide-band causal velocity
  estimate and then filtered (G is linear: G(X)θ = G(Xθ)), so a friction step is smoothed
  like the measured torque's.

``auto`` picks per joint the best the log offers: ``logged_external``, else ``logged_model``,
else the tool's own model (``inverse_dynamics``). :func:`choose_generators` says which and
why; a frozen per-joint choice (from ``calibrate``) on a log that lacks its channel is a
:class:`~impactcli.errors.LogFormatError` naming the joint and the channel.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError, LogFormatError, ModelError
from ..types import RobotLog
from .derivatives import MAX_CUTOFF_FRACTION, causal_derivatives, causal_lowpass, clip_cutoff

#: Generators of the tool's own identified model.
OWN_MODEL: tuple[str, ...] = ("inverse_dynamics", "momentum_observer")
#: Generators that read the controller's channels, with the channel each needs.
LOGGED: dict[str, str] = {"logged_external": "torque_ext", "logged_model": "torque_model"}
#: Every generator name, and ``auto``.
GENERATOR_CHOICES: tuple[str, ...] = ("auto", *OWN_MODEL, *LOGGED)

#: v_s of the correction's smooth Coulomb sign tanh(q'/v_s) [rad/s] (as the rigid models').
CORRECTION_SLOPE_RAD_S = 0.01
#: Names of the correction's parameters, in regressor order.
CORRECTION_PARAMS: tuple[str, ...] = ("scale", "fv", "fc", "offset")


@dataclass(frozen=True)
class GeneratorChoice:
    """Which generator one joint's residual comes from, and why (in words)."""

    joint: str
    generator: str
    reason: str

    def to_dict(self) -> dict[str, str]:
        """JSON-ready mapping (timeline ``replay.generator`` item)."""
        return {"generator": self.generator, "reason": self.reason}


def _check_name(name: str, where: str) -> None:
    if name not in GENERATOR_CHOICES:
        raise ConfigError(f"{where}: unknown residual generator {name!r} "
                          f"(one of {', '.join(GENERATOR_CHOICES)})")


def choose_generators(
    log: RobotLog, requested: str, frozen: Mapping[str, str] | None = None,
    *, frozen_where: str = "the config",
) -> tuple[GeneratorChoice, ...]:
    """Each joint's generator, in the log's joint order.

    Args:
        log: the log (which controller channels each joint carries).
        requested: ``auto`` or a generator name, for every joint.
        frozen: joint → generator frozen by a calibration; wins over ``requested`` for the
            joints it names.
        frozen_where: what holds ``frozen``, for messages.
    Raises:
        LogFormatError: a joint needs a channel the log lacks (names joint and channel).
        ConfigError: an unknown generator name.
    """
    _check_name(requested, "residual generator")
    has = {ch: log.has_channel(ch) for ch in LOGGED.values()}
    out = []
    for k, j in enumerate(log.joint_names):
        if frozen and j in frozen:
            g = frozen[j]
            _check_name(g, frozen_where)
            why = f"frozen by calibration in {frozen_where}"
        elif requested == "auto":
            if has["torque_ext"][k]:
                g, why = "logged_external", "auto: the log carries torque_ext"
            elif has["torque_model"][k]:
                g, why = "logged_model", "auto: the log carries torque_model (no torque_ext)"
            else:
                g, why = "inverse_dynamics", ("auto: no controller channel logged, the tool's "
                                              "own model")
        else:
            g, why = requested, "requested (--generator or the config's residual.generator)"
        if g in LOGGED and not has[LOGGED[g]][k]:
            raise LogFormatError(
                f"{log.source.path}: joint {j!r} has no {LOGGED[g]} channel, needed by the "
                f"{g} generator ({why})")
        out.append(GeneratorChoice(j, g, why))
    return tuple(out)


def needs_own_model(choices: tuple[GeneratorChoice, ...]) -> bool:
    """Whether any joint's residual comes from the tool's own identified model."""
    return any(c.generator in OWN_MODEL for c in choices)


def _features(
    log: RobotLog, cols: list[int], cutoff_hz: float, filter_torque: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, J, 4) correction regressors, (N, J) filtered torque and model torque."""
    dt = log.sample_period_s
    cutoff = clip_cutoff(cutoff_hz, 1.0 / dt, "derivative cut-off")
    q = log.position[:, cols]
    tau = log.torque[:, cols]
    assert log.torque_model is not None
    tm = log.torque_model[:, cols]
    if filter_torque:
        fast = 0.999 * MAX_CUTOFF_FRACTION / dt
        _, qd, _ = causal_derivatives(dt, q, fast)
    else:
        _, qd, _ = causal_derivatives(dt, q, cutoff)
    x = np.stack([tm, qd, np.tanh(qd / CORRECTION_SLOPE_RAD_S), np.ones_like(qd)], axis=2)
    if filter_torque:
        n, nj, p = x.shape
        x = causal_lowpass(x.reshape(n, nj * p), dt, cutoff).reshape(n, nj, p)
        tau = causal_lowpass(tau, dt, cutoff)
    return x, tau, x[:, :, 0]


def fit_logged_model_correction(
    logs: list[RobotLog], joints: tuple[str, ...], cutoff_hz: float, filter_torque: bool = True,
) -> dict[str, dict[str, float]]:
    """Per joint correction (a, f_v, f_c, c) of ``torque_model`` (module docstring),
    identified on collision-free ``logs`` by a robust fit of G tau − G τ_m.

    Args:
        logs: logs carrying ``torque_model`` for ``joints`` (the calibration logs, or the
            analysed log itself offline).
        joints: joints whose generator is ``logged_model``.
        cutoff_hz: the residual's causal filter G cut-off [Hz]; filter_torque as the residual.
    Returns:
        joint → {"scale": a, "fv": [N·m s/rad], "fc": [N·m], "offset": [N·m]}.
    """
    from .identify import IdentifyOptions, robust_lstsq

    if not joints:
        return {}
    xs, ys = [], []
    for log in logs:
        cols = [log.joint_names.index(j) for j in joints]
        x, tau_f, tm_f = _features(log, cols, cutoff_hz, filter_torque)
        xs.append(x)
        ys.append(tau_f - tm_f)
    x = np.concatenate(xs)
    y = np.concatenate(ys)
    n, nj, p = x.shape
    reg = np.zeros((n, nj, nj * p))
    for k in range(nj):
        reg[:, k, k * p:(k + 1) * p] = x[:, k, :]
        # a joint that never moves has a zero velocity column: keep the fit well posed
        for c in (1, 2):
            if not np.any(np.abs(x[:, k, c]) > 1e-12):
                reg[:, k, k * p + c] = 0.0
    theta, _, _ = robust_lstsq(reg, y, IdentifyOptions())
    if not np.all(np.isfinite(theta)):
        raise ModelError("the logged_model correction fit did not converge (non-finite)")
    return {j: {name: float(theta[k * p + i]) for i, name in enumerate(CORRECTION_PARAMS)}
            for k, j in enumerate(joints)}


def logged_residual(
    log: RobotLog, choices: tuple[GeneratorChoice, ...],
    correction: Mapping[str, Mapping[str, float]], cutoff_hz: float, filter_torque: bool,
) -> dict[str, np.ndarray]:
    """(N,) residual per joint whose generator reads the controller's channels.

    ``logged_external``: r = torque_ext as logged. ``logged_model``: r = G τ_m +
    G X θ − G tau (module docstring), with θ from ``correction`` (a joint missing from it is
    a :class:`~impactcli.errors.ConfigError`).
    """
    out: dict[str, np.ndarray] = {}
    ext = [c.joint for c in choices if c.generator == "logged_external"]
    for j in ext:
        assert log.torque_ext is not None
        out[j] = np.array(log.torque_ext[:, log.joint_names.index(j)], dtype=np.float64)
    lm = [c.joint for c in choices if c.generator == "logged_model"]
    if lm:
        missing = [j for j in lm if j not in correction]
        if missing:
            raise ConfigError(f"no logged_model correction for joint(s) {missing} "
                              "(residual.logged_model_correction)")
        cols = [log.joint_names.index(j) for j in lm]
        x, tau_f, tm_f = _features(log, cols, cutoff_hz, filter_torque)
        for k, j in enumerate(lm):
            th = np.array([correction[j][name] for name in CORRECTION_PARAMS])
            out[j] = tm_f[:, k] + x[:, k, :] @ th - tau_f[:, k]
    return out


def summary_name(choices: tuple[GeneratorChoice, ...]) -> str:
    """One name for the run: the generator every joint used, or ``mixed``."""
    names = {c.generator for c in choices}
    return names.pop() if len(names) == 1 else "mixed"


def choices_dict(choices: tuple[GeneratorChoice, ...]) -> dict[str, Any]:
    """joint → {generator, reason} (timeline ``replay.generator``)."""
    return {c.joint: c.to_dict() for c in choices}
