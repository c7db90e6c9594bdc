"""Model file: round trip, schema, shipped example, canonical sha256, bad files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from impactcli.errors import ModelError
from impactcli.model import RigidModel, identify_signals
from impactcli.run.model_files import read_model, write_model
from impactcli.schema import schema_dir, validate
from impactcli.types import JointSpec, RobotDescription

from .reference.two_link_arm import TwoLinkArm, multisine

JOINTS = ("shoulder", "elbow")
ARM = TwoLinkArm()


@pytest.fixture(scope="module", params=["planar", "decoupled"])
def model(request: pytest.FixtureRequest) -> RigidModel:
    t = np.arange(2000) * 0.004
    q, qd, qdd = multisine(t, 2, seed=3)
    robot = RobotDescription(
        joints=tuple(JointSpec(j) for j in JOINTS),
        kinematics={"type": "planar", "link_lengths": [ARM.l1, ARM.l2], "gravity": [0, -ARM.g]},
    )
    return identify_signals(q, qd, qdd, ARM.torque(q, qd, qdd), joint_names=JOINTS,
                            kind=request.param, robot=robot, input_sha256="cd" * 32)


def test_round_trip_through_a_file(model: RigidModel, tmp_path: Path) -> None:
    path = tmp_path / "model.json"
    write_model(model, path)
    validate(json.loads(path.read_text()), "model", ModelError, str(path))
    back = read_model(path)
    assert back.kind == model.kind and back.param_names == model.param_names
    np.testing.assert_array_equal(back.theta, model.theta)
    assert back.sha256 == model.sha256
    assert back.input_sha256 == "cd" * 32
    q = np.random.default_rng(0).normal(size=(50, 2))
    np.testing.assert_array_equal(back.predict(q, q, q), model.predict(q, q, q))
    assert not list(tmp_path.glob(".*part"))  # atomic write left nothing behind


def test_sha256_follows_the_content(model: RigidModel) -> None:
    d = model.to_dict()
    d["parameters"][0]["value"] += 1e-9
    assert RigidModel.from_dict(d).sha256 != model.sha256
    assert RigidModel.from_dict(model.to_dict()).sha256 == model.sha256


def test_shipped_example_is_valid_and_readable() -> None:
    path = schema_dir() / "examples" / "model.example.json"
    m = read_model(path)
    assert m.kind == "planar"
    assert m.fit["joints"]["holdout"] is not None


def test_bad_model_files_are_one_line_model_errors(model: RigidModel, tmp_path: Path) -> None:
    cases = {
        "missing.json": None,
        "garbage.json": "{not json",
        "wrong_kind.json": json.dumps({**model.to_dict(), "kind": "magic"}),
        "no_params.json": json.dumps(
            {k: v for k, v in model.to_dict().items() if k != "parameters"}),
        "renamed.json": json.dumps({**model.to_dict(), "joint_names": ["a", "b"]}),
    }
    for name, text in cases.items():
        p = tmp_path / name
        if text is not None:
            p.write_text(text)
        with pytest.raises(ModelError) as info:
            read_model(p)
        msg = str(info.value)
        assert name in msg and "\n" not in msg, msg
