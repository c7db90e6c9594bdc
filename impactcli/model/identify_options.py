"""The settings of identification (:func:`impactcli.model.identification.identify`).

A module of its own so the fit (:mod:`impactcli.model.fit`) and its sanity checks
(:mod:`impactcli.model.sanity`) can take the settings without importing the routine that
calls them. What each step does with them: docs/method.md §2, "Identification".
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import ModelError


@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of :func:`identify`.

    Attributes:
        cutoff_hz: zero-phase Butterworth cut-off for positions and torques [Hz]
            (clipped below 0.4 × sample rate). 10 Hz suits 100 Hz – 1 kHz logs of arm motion.
        filter_order: Butterworth order (one way; filtfilt doubles it).
        coulomb_slope_rad_s: v_s of the smooth sign tanh(q'/v_s) [rad/s] (the 0.01 rad/s
            default is measured: docs/models.md, "Identification options").
        offset: include a constant torque per joint.
        motor_inertia: include the reflected motor inertia Ia per joint (planar, urdf).
        filter_regressor: pass the regressor columns through the torque's zero-phase filter.
        robust: ``bisquare`` (Huber then Tukey bisquare), ``huber`` or ``none`` (plain LS).
        huber_k, bisquare_c: tuning constants, in robust standard deviations.
        max_iter: iteration cap of each reweighting stage.
        holdout_fraction: last fraction of the log held back for validation (0: none).
        min_holdout_s: hold back only when that part lasts at least this long [s].
        min_motion_rad: a joint whose position range is below this is "constant" [rad].
        allow_still_joints: a constant joint is an error by default; with this, it is
            warned about and its unexcited parameters are fixed at 0 (it keeps an offset).
            The CLI verbs (identify, calibrate, detect) all allow still joints.
        max_fit_samples: at most this many samples (fit + held back) enter the least
            squares; a longer log is fitted on every k-th filtered sample (memory and
            time stay bounded; the rows of a 10 Hz band-limited signal are correlated).
        drop_tolerance: relative QR pivot below which a parameter is "not excited".
        condition_warn: warn when the normalised regressor's condition number exceeds it.
        coupled_velocity_products: the coupled model also gets q'_k q'_l terms (k <= l)
            in every row (off by default: docs/models.md, "Identification options").
        ridge_lambdas: penalties tried for the coupled model's cross terms (relative to
            the column energy), besides "infinite" (cross terms off).
        ridge_folds: contiguous stretches of the blocked cross-validation that picks it.
        ridge_rule: ``1se`` (the strongest penalty whose cross-validated error is within one
            standard error, over the stretches, of the least: the conservative choice,
            docs/models.md, "Identification options") or ``min`` (the least error).
        coupled_max_mb: the coupled regressor (N × J × J(5J+1) numbers) is kept below this
            many MiB by fitting on every k-th sample (like ``max_fit_samples``).
        sanity_share: a negative inertia-like or friction parameter is warned about when
            its term's RMS is at least this fraction of the joint's torque RMS and at
            least the fit's robust residual scale (docs/method.md §2, "Fit sanity").
        check_sanity: run the fit-sanity checks (docs/method.md §2, "Fit sanity"). Off for
            a model of what the controller's channels leave out (the logged generators'
            correction), whose torque is a model error, not a joint's torque.
        still_speed_rad_s: a joint slower than this stands still [rad/s]: its friction is
            stiction, any torque within it, so no model predicts its torque there. A
            joint that stands still in more than half of the held-back part gets no
            relative held-back error. 0.01 rad/s: the Coulomb term's v_s.
        payload_per_log: with planar or URDF kinematics and two or more logs, weigh a
            payload per log against one load for all and fit it when clearly better
            held out (:func:`impactcli.model.selection.payload_errors`); False: one load.
    """

    cutoff_hz: float = 10.0
    filter_order: int = 4
    coulomb_slope_rad_s: float = 0.01
    offset: bool = True
    motor_inertia: bool = True
    filter_regressor: bool = True
    robust: str = "bisquare"
    huber_k: float = 1.345
    bisquare_c: float = 4.685
    max_iter: int = 50
    holdout_fraction: float = 0.2
    min_holdout_s: float = 2.0
    min_motion_rad: float = 1e-3
    allow_still_joints: bool = False
    max_fit_samples: int = 100_000
    drop_tolerance: float = 1e-4
    condition_warn: float = 1e3
    coupled_velocity_products: bool = False
    ridge_lambdas: tuple[float, ...] = tuple(float(10.0 ** (e / 2)) for e in range(-12, 3))
    ridge_folds: int = 10
    ridge_rule: str = "1se"
    coupled_max_mb: float = 256.0
    sanity_share: float = 0.02
    check_sanity: bool = True
    still_speed_rad_s: float = 0.01
    payload_per_log: bool = True

    def __post_init__(self) -> None:
        if self.robust not in ("bisquare", "huber", "none"):
            raise ModelError(f"robust must be bisquare, huber or none, got {self.robust!r}")
        if not 0.0 <= self.holdout_fraction < 0.9:
            raise ModelError(f"holdout_fraction must be in [0, 0.9), got {self.holdout_fraction}")
        if not self.coulomb_slope_rad_s > 0:
            raise ModelError("coulomb_slope_rad_s must be positive")
        if not self.ridge_lambdas or not all(v > 0 for v in self.ridge_lambdas):
            raise ModelError("ridge_lambdas must be positive numbers")
        if self.ridge_rule not in ("1se", "min"):
            raise ModelError(f"ridge_rule must be 1se or min, got {self.ridge_rule!r}")
        if self.ridge_folds < 2:
            raise ModelError(f"ridge_folds must be at least 2, got {self.ridge_folds}")
