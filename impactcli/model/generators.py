"""Residual generators per joint, including the controller's own channels
(docs/formats.md, "Model and detector config"; docs/method.md §2).

Four generators make the residual r ≈ tau_ext (eq. 8) that every detector evaluates:
``inverse_dynamics`` (eq. 7–8) and ``momentum_observer`` (De Luca) from the tool's own
identified rigid model (:mod:`impactcli.model.residual`); ``logged_external`` and
``logged_model`` from the controller's own channels ``torque_ext`` / ``torque_model``. A
controller's model error is linear in the rigid model's parameters (eq. 10), so by default
(``residual.logged_correction``) the tool identifies, with its own model structure, what the
channel leaves out and removes it: the identification target is tau − τ_m
(``logged_model``) or −torque_ext (``logged_external``), and r = Ŷθ − G(target). Without
the correction the channels are taken plain (r = torque_ext, or r = G τ_m − G tau). Why:
docs/controller_channels.md, "Residual generators: what each assumes".

``auto`` picks per joint the best the log offers: ``logged_external``, else ``logged_model``,
else the tool's own model (``inverse_dynamics``). :func:`choose_generators` says which and
why; a frozen per-joint choice (from ``calibrate``) on a log that lacks its channel is a
:class:`~impactcli.errors.LogFormatError` naming the joint and the channel.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError, LogFormatError
from ..types import RobotLog

#: Generators of the tool's own identified model.
OWN_MODEL: tuple[str, ...] = ("inverse_dynamics", "momentum_observer")
#: Generators that read the controller's channels, with the channel each needs.
LOGGED: dict[str, str] = {"logged_external": "torque_ext", "logged_model": "torque_model"}
#: Every generator name, and ``auto``.
GENERATOR_CHOICES: tuple[str, ...] = ("auto", *OWN_MODEL, *LOGGED)

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


def uses_correction(choices: tuple[GeneratorChoice, ...], correct: bool) -> bool:
    """Whether the logged joints' channels are corrected by an identified model."""
    return correct and any(c.generator in LOGGED for c in choices)


def target_log(log: RobotLog, choices: tuple[GeneratorChoice, ...], correct: bool) -> RobotLog:
    """The log whose ``torque`` the (correction) model is identified on and compared with.

    Per joint (module docstring): tau for the tool's own model; tau − τ_m for
    ``logged_model``; −torque_ext for ``logged_external`` — so that the inverse-dynamics
    residual Ŷθ − G(target) is, in every case, an estimate of the external torque. Without
    correction (``correct`` False) the log itself.
    """
    if not uses_correction(choices, correct):
        return log
    return dataclasses.replace(log, torque=target_torque(log, choices, correct), current=None,
                               torque_model=None, torque_ext=None)


def target_torque(log: Any, choices: tuple[GeneratorChoice, ...], correct: bool) -> np.ndarray:
    """(n, J) the torque of :func:`target_log`, for a log or a chunk of one (its
    ``torque``, ``torque_model``, ``torque_ext``)."""
    tau = np.array(log.torque, dtype=np.float64)
    if not uses_correction(choices, correct):
        return tau
    for k, c in enumerate(choices):
        if c.generator == "logged_model":
            assert log.torque_model is not None
            tau[:, k] = log.torque[:, k] - log.torque_model[:, k]
        elif c.generator == "logged_external":
            assert log.torque_ext is not None
            tau[:, k] = -log.torque_ext[:, k]
    return tau


def plain_residual(
    log: Any, choices: tuple[GeneratorChoice, ...], cutoff_hz: float, filter_torque: bool,
    dt: float | None = None, carry: Any = None,
) -> dict[str, np.ndarray]:
    """(n,) residual per logged joint without correction: r = torque_ext as logged, or
    r = G τ_m − G tau (``residual.logged_correction = false``).

    ``log``: a RobotLog, or a chunk of one with ``dt`` (the whole log's period [s]) and
    ``carry`` (:mod:`impactcli.model.causal`, the filters' state after the previous chunk)."""
    from .derivatives import causal_lowpass, clip_cutoff

    out: dict[str, np.ndarray] = {}
    dt = log.sample_period_s if dt is None else dt
    cutoff = clip_cutoff(cutoff_hz, 1.0 / dt, "derivative cut-off")
    for k, c in enumerate(choices):
        if c.generator == "logged_external":
            assert log.torque_ext is not None
            out[c.joint] = np.array(log.torque_ext[:, k], dtype=np.float64)
        elif c.generator == "logged_model":
            assert log.torque_model is not None
            d = log.torque_model[:, k] - log.torque[:, k]
            out[c.joint] = causal_lowpass(d, dt, cutoff, carry, f"logged_model.{c.joint}") \
                if filter_torque else np.array(d)
    return out


def formula(generator: str, correct: bool) -> str:
    """The residual of ``generator`` in symbols (for the timeline and the report)."""
    if generator in OWN_MODEL:
        return ("r = Y θ − G tau (eq. 7–8)" if generator == "inverse_dynamics"
                else "r: momentum observer of the identified model (De Luca)")
    if generator == "logged_external":
        return ("r = G torque_ext + Y θ (θ: what torque_ext reads in free motion)" if correct
                else "r = torque_ext")
    return ("r = G torque_model + Y θ − G tau (θ: what torque_model leaves out)" if correct
            else "r = G torque_model − G tau")


def summary_name(choices: tuple[GeneratorChoice, ...]) -> str:
    """One name for the run: the generator every joint used, or ``mixed``."""
    names = {c.generator for c in choices}
    return names.pop() if len(names) == 1 else "mixed"


def choices_dict(choices: tuple[GeneratorChoice, ...], correct: bool = True) -> dict[str, Any]:
    """joint → {generator, reason, residual} (timeline ``replay.generator``)."""
    return {c.joint: {**c.to_dict(), "residual": formula(c.generator, correct)}
            for c in choices}
