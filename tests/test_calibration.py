"""impactcli/run/calibration.py: what a calibration takes from its logs."""

from __future__ import annotations

import warnings

import pytest

from impactcli.errors import ImpactWarning
from impactcli.run.calibration import LABEL_GUARD_S, _one_load_each, calibrate_run
from impactcli.types import Labels

from .conftest import make_log


def test_a_log_whose_labels_list_a_payload_change_is_used_up_to_it() -> None:
    """A trial put a pick-and-place log (+1 kg at 20 s, −1 kg at 40 s, labelled) among its
    free logs: fitted with one load, vL came out 30× wider and every push of an audited log
    was missed. The log is now cut before its first labelled change (LABEL_GUARD_S[0]), and
    said; a log whose labels list none, or a change of no mass, is kept whole."""
    log = make_log(n=15000, dt=0.004)  # 60 s
    picks = Labels((), 250.0, "pnp.labels.json",
                   {"payload_changes": [{"t_s": 40.0, "mass_kg": -1.0},
                                        {"t_s": 20.0, "mass_kg": 1.0}]})
    nothing = Labels((), 250.0, "free.labels.json",
                     {"payload_changes": [{"t_s": 10.0, "mass_kg": 0.0}]})
    with pytest.warns(ImpactWarning, match=r"its labels list 2 payload change\(s\), the "
                      r"first at 20 s: used up to 19\.9 s only — the model weighs one load "
                      r"per log"):
        cut, whole, free = _one_load_each([log, log, log], [picks, None, nothing])
    assert cut.n_samples == round((20.0 - LABEL_GUARD_S[0]) / 0.004)
    assert cut.time_s[-1] < 20.0 - LABEL_GUARD_S[0] <= cut.time_s[-1] + 0.004
    assert whole is log and free is log


def test_calibrate_cuts_such_a_log_before_it_fits_the_model() -> None:
    """Through calibrate_run: the log cut is the one the thresholds see — the motion
    envelope counts its kept samples, 7525 fewer (60 s − 29.9 s at 250 Hz) than with the
    whole log (a causal replay: the warm-up is the same)."""
    log = make_log(n=15000, dt=0.004, seed=1)
    other = make_log(n=15000, dt=0.004, seed=2)
    picks = Labels((), 250.0, "pnp.labels.json",
                   {"payload_changes": [{"t_s": 30.0, "mass_kg": 1.0}]})
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        cut = calibrate_run([log, other], labels=[picks, None]).config.calibration
        whole = calibrate_run([log, other]).config.calibration
    assert any("used up to 29.9 s only" in str(w.message) for w in said)
    assert cut.motion_envelope is not None and whole.motion_envelope is not None
    assert whole.motion_envelope["samples"] - cut.motion_envelope["samples"] == 15000 - 7475
