"""A payload change as found (:mod:`impactcli.detect.payload_change`'s monitor finds it):
the change itself (:class:`PayloadChange`, the timeline's ``payload_changes`` item), a
contact found beside it (:class:`ContactPart`), how a contact in its alarm was judged
(:func:`contact_watch`) and a release that took off more than the log was seen to carry
(:func:`mass_check`). Records and their words' numbers only: no state. "The monitor's
step N" is a step of :mod:`impactcli.detect.payload_change`'s docstring.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: A contact beside a change (the monitor's step 5) when the torque the mass leaves
#: passes this many times vL: the mass is weighed on those samples, so its leftover is not
#: the free motion's residual vL was set on. Measured on the pick-and-place runs of
#: tests/benchmarks/payloads.py (2026-11-30), whose changes hold no contact: at 1 × vL
#: three of their 18 changes found one (1.06, 1.4 and 1.7 × vL: three false incidents);
#: at 2 × none, and the benchmark's figures are those without the test. A 30 N push
#: 0.5 s after a release leaves 17 × (tests/test_payload.py).
BESIDE = 2.0
#: A release takes off more than the log was seen to carry (:func:`mass_check`) when the
#: load it leaves falls below the least one seen by more than this share of the step's
#: mass and three of its standard errors: the weighing's own error (within 25 % on the
#: simulator's pick-and-place runs, docs/models.md) does not make one.
SHORTFALL = 0.25


def contact_watch(t_start: float, scanned_from: float, t_classified: float,
                  settle_s: float, lead_s: float = 0.0) -> dict[str, Any]:
    """How a contact in a change's alarm was judged (the timeline's ``contact_watch``):
    ``unjudged_s`` the stretches [s] where one joins the change's alarm, not counted — from
    the onset to where the scan for a contact beside the load began (module docstring, step
    5: the loading filter and the step settle), and from the classification for
    ``settle_s`` (an alarm that starts there is the change's:
    :func:`impactcli.detect.incidents.mark_payload_changes`, which also takes an alarm
    begun up to ``lead_s`` (``settle_s``) before the onset and still on at it) —;
    ``above_s`` the stretch scanned, where one is told apart when the torque the mass
    leaves passes ``above_times_vl`` × vL (:data:`BESIDE`)."""
    return {"unjudged_s": [[t_start - lead_s, scanned_from],
                           [t_classified, t_classified + settle_s]],
            "above_s": [scanned_from, t_classified], "above_times_vl": BESIDE}


def mass_check(mass_kg: float, mass_se_kg: float, lowest_kg: float, after_kg: float,
               start_weighed: bool = True) -> str | None:
    """A release (``mass_kg`` < 0) that leaves the arm carrying ``after_kg`` (beyond the
    model's load) below ``lowest_kg`` — the least load it was seen with so far: the
    model's (0), the start's and those after earlier changes — by more than
    :data:`SHORTFALL` of the step and three of its standard errors: it took off more than
    the log was seen to carry. The words, or None: possible only if the load it started
    with was not weighed (``start_weighed`` False) or the calibration's lightest log carried
    that much beyond the arm's own (the model took it for the arm); else the torque's scale
    or the model is off."""
    short = lowest_kg - after_kg
    if not (mass_kg < 0 and short > max(SHORTFALL * abs(mass_kg), 3.0 * mass_se_kg)):
        return None
    why = ("the load the log started with was not weighed (input.payload), so it may have "
           "carried it from the start; else " if not start_weighed else "possible only if ")
    return (f"released {-mass_kg:.3g} kg, {short:.3g} kg more than the log was seen to carry "
            f"(the least load it was seen with: {lowest_kg:+.3g} kg beyond the model's) — "
            f"{why}the calibration's lightest log carried that much beyond the arm's own (a "
            "tool the model took for the arm); else the torque's scale or the model is off, "
            "and this mass cannot be trusted")


@dataclass(frozen=True)
class ContactPart:
    """A contact beside a payload change, apart from the load (the monitor's step 5):
    over the rows of its excursion, ``r`` (n, J) the residual with the load's torque taken
    out (r + Y B π) [N·m], ``ratio`` (n, J) its static-loading statistic over vL, ``q``
    and ``qd`` (n, J) the filtered positions [rad] and velocities [rad/s] of ``joints``
    (the replay's), and the sample period ``dt`` [s]: what the incident builder needs to
    place and size the contact itself (:func:`impactcli.detect.incident_builder.beside`);
    ``began_before``: the excursion was already on where the torque the load leaves is
    first read (the onset plus ``settle_s``), so its rows hold the contact's end only."""

    joints: tuple[str, ...]
    r: np.ndarray
    ratio: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    dt: float
    began_before: bool = False


@dataclass(frozen=True)
class PayloadChange:
    """A payload change (the monitor's): ``t_start`` the alarm's onset, ``t_classified``
    when it was classified and the residual took the new load [s since the log's first
    sample]; the mass change [kg] and its standard error; ``values`` the load's parameters
    (:func:`impactcli.model.payload.basis`' names, SI); ``explained`` the share of the
    window's residual energy the mass explains (its confidence, 0–1); ``mass_after_kg`` the
    load then carried beyond the config's model's (the lightest calibration log's);
    ``as_log`` the calibration log whose fitted load that is (the monitor's step 4;
    None: the weighed step is taken as it is); ``drift`` and ``inertia`` what the tests
    (d) and (e) found; ``at_watch_start``: the alarm was on when the watch began (the
    warm-up's least length), so the change may have come earlier, in the warm-up (with
    ``start_unknown``, the log's start could not weigh its load: most likely that load);
    ``contact``: a contact in the window beside the mass (the monitor's step 5): the
    sample index ``i`` and time ``t_s`` [s] where the excursion of the static-loading
    statistic of the torque the mass leaves, above vL, that holds its peak began (the
    alarm's onset when it began before what the monitor keeps), the ``joint`` and its
    ``peak`` over vL, and ``counted: False`` when no incident holds it
    (:func:`impactcli.detect.incidents.mark_payload_changes`); None: none.
    ``scanned_from`` [s]: where that scan began (the onset plus ``settle_s``, or the
    oldest row the monitor kept), for :func:`contact_watch` (with ``settle_s`` and the
    lead ``lead_s``, :func:`impactcli.detect.incidents.mark_payload_changes`); None: not
    recorded. ``mass_check``: the words of a release that took off more than the log was
    seen to carry (:func:`mass_check`), None when it did not. ``carried_since_s`` [s]: the
    load is in all the motion the monitor keeps before the onset, from then on — its step
    came then or before, under the thresholds until the motion grew its torque, so the
    onset is not the step's (None: the step is the onset's, or no earlier one is kept)."""

    t_start: float
    t_classified: float
    mass_kg: float
    mass_se_kg: float
    values: dict[str, float]
    explained: float
    mass_after_kg: float
    as_log: str | None = None
    drift: float | None = None
    inertia: str | None = None
    at_watch_start: bool = False
    contact: dict[str, Any] | None = None
    part: ContactPart | None = field(default=None, repr=False, compare=False)
    scanned_from: float | None = None
    settle_s: float = 0.0
    lead_s: float = 0.0
    mass_check: str | None = None
    start_unknown: bool = False
    carried_since_s: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (the timeline's ``payload_changes`` item)."""
        d = {"t_start": self.t_start, "t_classified": self.t_classified,
             "mass_kg": self.mass_kg, "mass_se_kg": self.mass_se_kg,
             "values": dict(self.values), "explained": self.explained,
             "mass_after_kg": self.mass_after_kg,
             **({} if self.drift is None else {"drift": self.drift}),
             **({} if self.inertia is None else {"inertia": self.inertia})}
        if self.as_log is not None:
            d["as_log"] = self.as_log
        d.update({k: True for k, on in (("at_watch_start", self.at_watch_start),
                                        ("start_unknown", self.start_unknown)) if on})
        if self.carried_since_s is not None:
            d["carried_since_s"] = self.carried_since_s
        if self.contact is not None:
            d["contact"] = dict(self.contact)
        if self.scanned_from is not None:
            d["contact_watch"] = contact_watch(self.t_start, self.scanned_from,
                                               self.t_classified, self.settle_s, self.lead_s)
        if self.mass_check is not None:
            d["mass_check"] = self.mass_check
        return d
