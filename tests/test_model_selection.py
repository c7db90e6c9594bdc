"""The model kind chosen by held-back error (impactcli/model/selection.py, docs/models.md,
"Choosing the model"): against data of known structure, through the API and the CLI."""

from __future__ import annotations

import hashlib
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from impactcli.config import DetectorConfig, load_config, save_config
from impactcli.logs import read_log, write_log
from impactcli.model import IdentifyOptions, identify
from impactcli.model.identification import fit_rows, prepare_rows
from impactcli.model.selection import folds_of, one_se, select_model
from impactcli.run.model_files import read_model
from impactcli.types import LogSource, RobotLog

from .cli_run import cli
from .conftest import read_kuka
from .reference.two_link_arm import TwoLinkArm, multisine

JOINTS = ("shoulder", "elbow")
ARM = TwoLinkArm()
OPTS = IdentifyOptions(allow_still_joints=True)


def _log(q: np.ndarray, tau: np.ndarray, name: str, dt: float = 0.004) -> RobotLog:
    t = np.arange(q.shape[0]) * dt
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=JOINTS, position=q,
                    torque=tau, source=LogSource(name, hashlib.sha256(name.encode()).hexdigest(),
                                                 "memory"))


def _derivs(q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    qd = np.gradient(q, dt, axis=0)
    return qd, np.gradient(qd, dt, axis=0)


def arm_logs(k: int = 3, n: int = 4000) -> list[RobotLog]:
    """Multi-sine runs of the exact 2-link arm (coupled dynamics), other seeds each."""
    out = []
    for s in range(k):
        t = np.arange(n) * 0.004
        q, qd, qdd = multisine(t, 2, seed=11 + s)
        tau = ARM.torque(q, qd, qdd) + np.random.default_rng(s).normal(0, 0.02, (n, 2))
        out.append(_log(q, tau, f"arm{s}.csv"))
    return out


def decoupled_truth(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Each joint alone: inertia, gravity of its own angle, friction, offset."""
    return np.stack([0.4 * qdd[:, 0] + 3.0 * np.cos(q[:, 0]) + 0.3 * qd[:, 0]
                     + 0.4 * np.tanh(qd[:, 0] / 0.01) + 0.1,
                     0.2 * qdd[:, 1] - 1.5 * np.sin(q[:, 1]) + 0.2 * qd[:, 1]
                     + 0.25 * np.tanh(qd[:, 1] / 0.01) - 0.05], axis=1)


# ------------------------------------------------------------------ the parts and the rule
def test_leave_one_log_out_holds_back_each_log_whole() -> None:
    folds, how = folds_of([5, 3, 4], ["a", "b", "c"], gap=2)
    assert how == "leave-one-log-out over 3 logs"
    assert [f.name for f in folds] == ["log a", "log b", "log c"]
    assert folds[1].test.tolist() == [5, 6, 7]
    assert folds[1].train.tolist() == [0, 1, 2, 3, 4, 8, 9, 10, 11]


def test_one_log_is_cut_into_contiguous_stretches_with_a_margin() -> None:
    folds, how = folds_of([20], ["a"], gap=2, stretches=4)
    assert "4 contiguous stretches" in how and "margin 2" in how
    assert folds[1].test.tolist() == [5, 6, 7, 8, 9]
    # the stretch and 2 rows on each side are not fitted
    assert folds[1].train.tolist() == [0, 1, 2, *range(12, 20)]
    assert folds[0].train.tolist() == list(range(7, 20))   # the first has no left margin
    assert sorted(np.concatenate([f.test for f in folds]).tolist()) == list(range(20))


def test_one_standard_error_rule_prefers_the_simpler_within_one_se() -> None:
    # candidates simplest first; held-back parts in columns
    rel = np.array([[1.00, 1.10, 0.90],     # mean 1.00: beyond the least + one SE
                    [0.99, 0.99, 0.99],     # mean 0.99: within one SE of the least
                    [0.96, 1.00, 0.98]])    # mean 0.98: the least
    chosen, least, se = one_se(rel)
    assert least == 2
    assert se == pytest.approx(np.std(rel[2], ddof=1) / np.sqrt(3))   # 0.0115
    assert chosen == 1


def test_one_standard_error_rule_takes_the_richer_when_clearly_better() -> None:
    rel = np.array([[1.0, 1.1, 0.9], [0.5, 0.52, 0.48]])
    chosen, least, _se = one_se(rel)
    assert (chosen, least) == (1, 1)
    rel = np.array([[0.50, 0.51, 0.49], [0.49, 0.60, 0.40]])  # better on average, not clearly
    chosen, least, _ = one_se(rel)
    assert (chosen, least) == (0, 1)


def test_the_richer_must_also_cut_the_held_back_rms_by_min_gain() -> None:
    rel = np.array([[1.0, 1.02, 0.98], [0.80, 0.81, 0.79]])   # clearly beyond one SE
    assert one_se(rel)[0] == 1
    assert one_se(rel, np.array([1.0, 0.80]), min_gain=0.25)[0] == 0   # a 20 % cut
    assert one_se(rel, np.array([1.0, 0.70]), min_gain=0.25)[0] == 1   # a 30 % cut


# ------------------------------------------------------------------ known truth
def test_a_coupled_arm_gets_the_coupled_model_with_its_reason() -> None:
    m = select_model(arm_logs(), options=OPTS)
    sel = m.fit["selection"]
    assert m.kind == sel["chosen"] == "coupled"
    assert sel["held_back"] == "leave-one-log-out over 3 logs"
    assert sel["parts"] == ["log arm0.csv", "log arm1.csv", "log arm2.csv"]
    for j in JOINTS:
        e = sel["joints"][j]
        assert e["chosen"] == "coupled" and e["lambda"] > 0
        assert e["coupled"]["rms_nm"] < 0.5 * e["decoupled"]["rms_nm"]
        assert e["coupled"]["better_parts"] == 3
        assert len(e["decoupled"]["parts_rms_nm"]) == 3
    assert sel["reason"].startswith("coupled: held-back error ")
    assert "on 3 of 3 held-out logs" in sel["reason"]
    # the model is fitted on all logs with the chosen penalties
    assert {j: v.get("lambda") for j, v in m.fit["ridge"]["joints"].items()} == {
        j: sel["joints"][j]["lambda"] for j in JOINTS}
    assert m.filter["logs"] == ["arm0.csv", "arm1.csv", "arm2.csv"]


def test_an_uncoupled_arm_keeps_the_decoupled_model_exactly() -> None:
    logs = []
    for s in range(3):
        t = np.arange(4000) * 0.004
        q, qd, qdd = multisine(t, 2, seed=21 + s)
        tau = decoupled_truth(q, qd, qdd) + np.random.default_rng(s).normal(0, 0.02, (4000, 2))
        logs.append(_log(q, tau, f"free{s}.csv"))
    m = select_model(logs, options=OPTS)
    sel = m.fit["selection"]
    assert m.kind == "decoupled", sel["reason"]
    assert sel["reason"].startswith("decoupled: coupled is ")
    assert all(sel["joints"][j]["chosen"] == "decoupled" for j in JOINTS)
    # the same model identification makes of these logs as decoupled
    from impactcli.model import identify_many

    plain = identify_many(logs, kind="decoupled", options=OPTS)
    assert np.array_equal(m.theta, plain.theta)
    assert {k: v for k, v in m.fit.items() if k != "selection"} == plain.fit


def test_a_coupling_seen_in_one_motion_only_does_not_carry_over() -> None:
    """A disturbance on the shoulder that follows the elbow's motion in one log only (e.g.
    a cable pulled by the elbow on that path): a coupled model fitted on that log explains
    it by cross terms, judged on its own stretches it looks better; held out across logs
    of other motions it is not, and decoupled is kept."""
    n, dt = 5000, 0.004
    t = np.arange(n) * dt
    logs = []
    for s in range(3):
        q, qd, qdd = multisine(t, 2, seed=31 + s)
        tau = decoupled_truth(q, qd, qdd) + np.random.default_rng(s).normal(0, 0.02, (n, 2))
        if s == 0:
            tau[:, 0] += 2.0 * np.sin(q[:, 1])   # only in this motion
        logs.append(_log(q, tau, f"family{s}.csv"))
    alone = select_model(logs[:1], options=OPTS).fit["selection"]
    assert alone["joints"]["shoulder"]["chosen"] == "coupled"      # its own stretches
    across = select_model(logs, options=OPTS).fit["selection"]
    e = across["joints"]["shoulder"]
    assert e["chosen"] == "decoupled", e["reason"]
    assert e["coupled"]["better_parts"] < 3


def test_the_coupled_fit_uses_the_chosen_penalties() -> None:
    logs = arm_logs(2)
    m = select_model(logs, options=OPTS)
    lam = [m.fit["selection"]["joints"][j].get("lambda", float("inf")) for j in JOINTS]
    rows = [prepare_rows(lg, None, "coupled", OPTS) for lg in logs]
    direct = fit_rows(rows, [lg.source.path for lg in logs], robot=None, options=OPTS,
                      input_sha256=m.input_sha256, lambdas=lam)
    assert np.array_equal(direct.theta, m.theta)


def test_kinematics_name_the_kind_and_its_held_back_error_is_shown() -> None:
    from impactcli.types import JointSpec, RobotDescription

    robot = RobotDescription(joints=tuple(JointSpec(j) for j in JOINTS), kinematics={
        "type": "planar", "link_lengths": [ARM.l1, ARM.l2], "gravity": [0.0, -ARM.g]},
        path="robot.json")
    logs = arm_logs(2)
    m = select_model(logs, robot=robot, options=OPTS)
    sel = m.fit["selection"]
    assert m.kind == sel["chosen"] == "planar" and sel["named"] is True
    assert "planar: the robot's kinematics (--robot), used as named" in sel["reason"]
    for j in JOINTS:  # the exact model is the best held back
        assert sel["joints"][j]["planar"]["rms_nm"] < sel["joints"][j]["decoupled"]["rms_nm"]
    from impactcli.model import identify_many

    assert np.array_equal(m.theta, identify_many(logs, robot=robot, options=OPTS).theta)


# ------------------------------------------------------------------ the model file
@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_the_record_survives_the_model_file_and_a_config(tmp_path: Path, suffix: str) -> None:
    m = select_model(arm_logs(2), options=OPTS)
    from impactcli.run.model_files import write_model

    write_model(m, tmp_path / "m.json")
    back = read_model(tmp_path / "m.json")
    assert back.fit["selection"] == json.loads(json.dumps(m.fit["selection"]))
    cfg = DetectorConfig(model=m.to_dict())
    save_config(cfg, tmp_path / f"c{suffix}")
    assert load_config(tmp_path / f"c{suffix}").model == m.to_dict()


# ------------------------------------------------------------------ through the CLI
def test_identify_without_kind_prints_the_choice_and_records_it(tmp_path: Path) -> None:
    log = tmp_path / "arm.csv"
    write_log(arm_logs(1, 5000)[0], log)
    code, out, err = cli(["identify", str(log), "-o", str(tmp_path / "m.json")])
    assert code == 0, err
    assert "model kind: coupled: held-back error " in out
    assert "of 5 held-back stretches" in out
    assert "held back: 5 contiguous stretches of the log held back in turn" in out
    m = read_model(tmp_path / "m.json")
    assert m.kind == "coupled" and m.fit["selection"]["chosen"] == "coupled"


def test_identify_with_kind_uses_it_as_named(tmp_path: Path) -> None:
    log = tmp_path / "arm.csv"
    write_log(arm_logs(1, 5000)[0], log)
    code, out, err = cli(["identify", str(log), "--kind", "decoupled",
                          "-o", str(tmp_path / "m.json")])
    assert code == 0, err
    assert "model kind:" not in out
    m = read_model(tmp_path / "m.json")
    assert m.kind == "decoupled" and "selection" not in m.fit


def test_detect_without_config_uses_the_kind_that_predicts_best(tmp_path: Path) -> None:
    log = tmp_path / "arm.csv"
    write_log(arm_logs(1, 5000)[0], log)
    code, _out, err = cli(["detect", str(log), "-o", str(tmp_path / "out")])
    assert code == 0, err
    tl = json.loads((tmp_path / "out" / "arm.timeline.json").read_text())
    model = tl["model"]["model"]
    assert tl["model"]["source"] == "identified-from-log"
    assert model["kind"] == "coupled"
    sel = model["fit"]["selection"]
    assert sel["held_back"].startswith("5 contiguous stretches")
    # the same choice as identify makes of the log
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = select_model([read_log(log)], options=OPTS)
    assert sel["joints"] == json.loads(json.dumps(ident.fit["selection"]["joints"]))


def test_detect_without_config_on_an_uncoupled_arm_keeps_decoupled(tmp_path: Path) -> None:
    t = np.arange(5000) * 0.004
    q, qd, qdd = multisine(t, 2, seed=41)
    tau = decoupled_truth(q, qd, qdd) + np.random.default_rng(1).normal(0, 0.02, (5000, 2))
    log = tmp_path / "free.csv"
    write_log(_log(q, tau, "free.csv"), log)
    code, _, err = cli(["detect", str(log), "-o", str(tmp_path / "out")])
    assert code == 0, err
    model = json.loads((tmp_path / "out" / "free.timeline.json").read_text())["model"]["model"]
    assert model["kind"] == "decoupled"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = identify(read_log(log), kind="decoupled", options=IdentifyOptions(
            allow_still_joints=True))
    assert [p["value"] for p in model["parameters"]] == plain.theta.tolist()


# ------------------------------------------------------------------ real arms
def test_on_the_real_kuka_log_coupled_is_chosen_where_it_predicts_better(
        real_logs: Path) -> None:
    log = read_kuka(real_logs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = select_model([log], options=OPTS)
    sel = m.fit["selection"]
    assert m.kind == "coupled"
    for j in ("a2", "a3", "a4"):  # the coupling-loaded joints: several times better
        e = sel["joints"][j]
        assert e["chosen"] == "coupled"
        assert e["coupled"]["rms_nm"] < 0.35 * e["decoupled"]["rms_nm"]
    for j in ("a5", "a6"):  # wrist joints: no coupling the terms can use
        assert sel["joints"][j]["chosen"] == "decoupled"


def test_on_the_real_ur_log_the_still_wrist_stays_decoupled(real_logs: Path) -> None:
    log = read_log(real_logs / "ur_ext_observer" / "link4.csv", channel_map="ur_ext_observer")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = select_model([log], options=OPTS)
    sel = m.fit["selection"]
    assert "coupled" not in sel["joints"]["wrist_3"]   # it never moves
    assert sel["joints"]["wrist_3"]["chosen"] == "decoupled"
    e = sel["joints"]["elbow"]
    assert e["chosen"] == "coupled"
    assert e["coupled"]["rms_nm"] < 0.8 * e["decoupled"]["rms_nm"]


# ------------------------------------------------------------------ calibrate's call
def test_calibrate_with_the_chosen_model_then_detect(tmp_path: Path) -> None:
    """The call run/calibration.py is to make when no model is given (select_model in place
    of identify_many), then `detect --config` on another run of the arm."""
    from impactcli.run.calibration import calibrate

    free = arm_logs(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = select_model(free, options=OPTS)
        cfg = calibrate(free, model=model, generator="inverse_dynamics")
    assert cfg.model is not None and cfg.model["fit"]["selection"]["chosen"] == "coupled"
    save_config(cfg, tmp_path / "c.toml")
    other = tmp_path / "other.csv"
    t = np.arange(4000) * 0.004
    q, qd, qdd = multisine(t, 2, seed=99)
    write_log(_log(q, ARM.torque(q, qd, qdd), "other.csv"), other)
    code, _, err = cli(["detect", str(other), "--config", str(tmp_path / "c.toml"),
                        "-o", str(tmp_path / "out")])
    assert code == 0, err
    tl = json.loads((tmp_path / "out" / "other.timeline.json").read_text())
    assert tl["model"]["source"] == "config"
    assert tl["model"]["model"]["kind"] == "coupled"
    assert tl["model"]["sha256"] == cfg.calibration.model_sha256


def test_kinematics_that_predict_worse_than_none_are_warned_of(tmp_path: Path) -> None:
    """A trial's robot file listed the joints out of chain order: its planar model, used
    as named, predicted the held-back torque 1.85× worse than the coupled model without
    kinematics, and the only warning blamed a torque's sign. The sample ASSIST-like arm's
    own description is 0.75–0.9× the coupled error (no warning); with its two joints
    swapped the named kinematics are warned of, naming the joint and both errors."""
    import json

    from impactcli.errors import ImpactWarning
    from impactcli.logs.robot_files import read_robot
    from impactcli.model.selection import MISFIT_FACTOR, _named_misfit

    per = {"a": {"decoupled": {"rms_nm": 0.4}, "coupled": {"rms_nm": 0.2},
                 "planar": {"rms_nm": 0.2 * MISFIT_FACTOR}},
           "b": {"decoupled": {"rms_nm": 0.4}, "planar": {"rms_nm": 0.3}}}
    assert _named_misfit("planar", per, ["x.csv"]) is None  # at the factor: not beyond
    per["a"]["planar"]["rms_nm"] = 0.31
    said = _named_misfit("planar", per, ["x.csv"])
    assert said is not None and said.startswith(
        "x.csv: the robot's planar kinematics predict the held-back torque of a worse than "
        "a model without them (a: 0.31 against 0.2 N·m RMS)")
    csv = Path(__file__).resolve().parents[1] / "sample_logs" / "csv"
    logs = [read_log(csv / f"assist_free_{m}.csv.gz")
            for m in ("triangle", "p2p", "multisine")]
    path = csv / "assist_free_triangle.robot.json"
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        select_model(logs, robot=read_robot(path), options=OPTS)
    assert not [w for w in got if "kinematics predict" in str(w.message)]
    doc = json.loads(path.read_text("utf-8"))
    doc["joints"] = doc["joints"][::-1]
    swapped = tmp_path / "swapped.json"
    swapped.write_text(json.dumps(doc), "utf-8")
    with warnings.catch_warnings(record=True) as got:  # with a negative inertia's too
        warnings.simplefilter("always")
        select_model(logs, robot=read_robot(swapped), options=OPTS)
    assert any(w.category is ImpactWarning and "the robot's planar kinematics predict the "
               "held-back torque of " in str(w.message) for w in got), [str(w.message)
                                                                       for w in got]
