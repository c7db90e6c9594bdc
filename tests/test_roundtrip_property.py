"""Everything the tool writes, it reads back unchanged: configs (TOML, YAML, JSON, with the
model they embed), models, labels, robot descriptions and timelines.

Documents are drawn from the schemas' own value space (tests/schema_strategies.py): nulls
where allowed, empty tables, non-ASCII names, floats from subnormal to 1e308. For each,
the tool either refuses the document with its one-line error (a value the schema allows
but a cross-field rule forbids) or writes it, reads the file back to the same mapping,
and writes the same bytes again. The budget is bounded and seeded (``derandomize``), so
``make test`` is repeatable.
"""

from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from impactcli.cli import main
from impactcli.config import DetectorConfig, dumps_config, load_config, save_config
from impactcli.errors import ConfigError, LabelsError, ModelError, RobotDescriptionError
from impactcli.logs import read_log, write_log
from impactcli.logs.paths import RECORDED_READ_OPTIONS
from impactcli.logs.robot_files import (
    labels_from_dict,
    read_labels,
    read_robot,
    robot_from_dict,
    write_labels,
    write_robot,
)
from impactcli.model import RigidModel, structures
from impactcli.outputs.timeline import dumps_timeline, read_timeline
from impactcli.run.model_files import read_model, write_model
from impactcli.schema import load_schema
from impactcli.types import ReadOptions
from tests.schema_strategies import from_schema

PROPERTY = settings(max_examples=60, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                           HealthCheck.data_too_large])

_MODEL = load_schema("model")
_FINITE = st.floats(allow_nan=False, allow_infinity=False)
_POSITIVE = st.floats(min_value=1e-300, max_value=1e300, allow_nan=False)
_JOINTS = st.lists(from_schema("model", _MODEL["properties"]["joint_names"]["items"]),
                   min_size=1, max_size=3, unique=True)


@st.composite
def model_docs(draw: st.DrawFn) -> dict[str, Any]:
    """Model mappings of every kind but urdf (its parameter names need a URDF and
    pinocchio: covered by tests/test_model_urdf.py), whose parameter names match their
    structure, with the fit (and in half of them a model-kind selection record), filter
    and robot drawn from the schema."""
    kind = draw(st.sampled_from(["decoupled", "coupled", "planar"]))
    joints = tuple(draw(_JOINTS))
    structure: dict[str, Any] = {"coulomb_slope_rad_s": draw(_POSITIVE),
                                 "offset": draw(st.booleans()),
                                 "motor_inertia": draw(st.booleans())}
    if kind == "coupled":
        structure["velocity_products"] = draw(st.booleans())
    if kind == "planar":
        structure["link_lengths"] = draw(st.lists(_POSITIVE, min_size=len(joints),
                                                  max_size=len(joints)))
        structure["gravity"] = draw(st.lists(_FINITE, min_size=2, max_size=2))
    names = structures.param_names(kind, joints, structure)
    props = _MODEL["properties"]
    doc: dict[str, Any] = {
        "schema_version": "1.0",
        "tool": {"name": "impactcli", "version": draw(st.text(max_size=8))},
        "kind": kind,
        "joint_names": list(joints),
        "parameters": [{"name": n, "value": draw(_FINITE)} for n in names],
        "structure": structure,
        "filter": draw(from_schema("model", props["filter"])),
        "fit": draw(from_schema("model", props["fit"])),
        "input_sha256": draw(st.text(max_size=8)),
    }
    if draw(st.booleans()):  # the model-kind selection's record (model/selection.py), always
        doc["fit"]["selection"] = draw(from_schema(  # drawn in half the documents
            "model", props["fit"]["properties"]["selection"]))
    robot = draw(st.one_of(st.none(), from_schema("robot")))
    if robot is not None or draw(st.booleans()):
        doc["robot"] = robot  # absent and null both mean "no robot description"
    return doc


@st.composite
def config_docs(draw: st.DrawFn) -> dict[str, Any]:
    """Config mappings from the config schema, with or without an embedded model; the
    threshold tables of a config with a model name the model's joints (the config's rule)."""
    doc: dict[str, Any] = draw(from_schema("config"))
    doc.pop("model", None)
    env = (doc.get("calibration") or {}).get("motion_envelope") or {}
    for q in (env.get("joints") or {}).values():  # a range is [min, max] (a cross-field rule)
        for k, rng in q.items():
            q[k] = sorted(rng)
    if draw(st.booleans()):
        model = draw(model_docs())
        doc["model"] = model
        values = st.floats(min_value=0, max_value=1e300, allow_nan=False)
        thresholds = {}
        for kind in draw(st.lists(st.sampled_from(["v_stat", "v0", "vL"]), unique=True)):
            thresholds[kind] = {j: draw(values) for j in model["joint_names"]}
        doc["thresholds"] = thresholds
    return doc


@contextmanager
def _tmp() -> Iterator[Path]:
    """A folder for one drawn example, removed after it (hundreds are drawn per run)."""
    with tempfile.TemporaryDirectory(prefix="impactcli-roundtrip-") as folder:
        yield Path(folder)


def _writes_back(obj: Any, write: Callable[[Any, Path], Any], read: Callable[[Path], Any],
                 name: str) -> Any:
    """``obj`` written to a file ``name``, read back, and written again to the same bytes;
    what was read back."""
    with _tmp() as folder:
        path = folder / name
        write(obj, path)
        text = path.read_text("utf-8")
        back = read(path)
        write(back, path)
        assert path.read_text("utf-8") == text
    return back


@pytest.mark.parametrize("suffix", [".toml", ".yaml", ".json"])
@PROPERTY
@given(doc=config_docs())
def test_config_round_trip(suffix: str, doc: dict[str, Any]) -> None:
    try:
        cfg = DetectorConfig.from_dict(doc, "<drawn>")
    except ConfigError:
        assume(False)  # refused with the one-line error: a cross-field rule
        return
    with _tmp() as folder:
        path = folder / f"config{suffix}"
        save_config(cfg, path)
        text = path.read_text("utf-8")
        back = load_config(path)
        assert back.to_dict() == cfg.to_dict()
        assert dumps_config(back, suffix) == text


@PROPERTY
@given(doc=model_docs())
def test_model_round_trip(doc: dict[str, Any]) -> None:
    try:
        model = RigidModel.from_dict(doc, "<drawn>")
    except ModelError:
        assume(False)
        return
    back = _writes_back(model, write_model, read_model, "model.json")
    assert back.to_dict() == model.to_dict()
    assert back.sha256 == model.sha256


@PROPERTY
@given(doc=from_schema("labels"))
def test_labels_round_trip(doc: dict[str, Any]) -> None:
    try:
        labels = labels_from_dict(doc, "<drawn>")
    except LabelsError:
        assume(False)  # an end before its start
        return
    back = _writes_back(labels, write_labels, read_labels, "x.labels.json")
    assert back.to_dict() == labels.to_dict()


@PROPERTY
@given(doc=from_schema("robot"))
def test_robot_round_trip(doc: dict[str, Any]) -> None:
    try:
        robot = robot_from_dict(doc, "<drawn>")
    except RobotDescriptionError:
        assume(False)  # e.g. planar link lengths that do not match the joints
        return
    with _tmp() as folder:
        path = folder / "sub" / "x.robot.json"
        path.parent.mkdir()
        write_robot(robot, path)
        text = path.read_text("utf-8")
        back = read_robot(path)
        write_robot(back, path)
        assert path.read_text("utf-8") == text


@PROPERTY
@given(doc=from_schema("timeline"))
def test_timeline_round_trip(doc: dict[str, Any]) -> None:
    with _tmp() as folder:
        path = folder / "x.timeline.json"
        text = dumps_timeline(doc)
        path.write_text(text, "utf-8")
        back = read_timeline(path)
        assert back == doc
        assert dumps_timeline(back) == text


_TEXT = st.text(min_size=1, max_size=12)
_READ_OPTIONS = st.builds(
    ReadOptions, channel_map=st.none() | _TEXT, topic=st.none() | _TEXT,
    reference_topic=st.none() | _TEXT,
    time_source=st.none() | st.sampled_from(["log", "publish", "header"]),
    torque_source=st.none() | st.sampled_from(["torque", "current"]),
    time_unit=st.none() | st.sampled_from(["s", "ms", "us", "ns"]),
    time_column=st.none() | _TEXT,
    rate=st.none() | st.floats(min_value=1e-3, max_value=1e6, allow_nan=False),
    position_unit=st.none() | st.sampled_from(["rad", "deg"]), repair_order=st.booleans())


@PROPERTY
@given(opts=_READ_OPTIONS)
def test_read_options_round_trip(opts: ReadOptions) -> None:
    """The read options a timeline records (``input.read_options``) read back as the same
    options, through the JSON the timeline is written as."""
    import json

    recorded = json.loads(json.dumps(opts.as_dict(), allow_nan=False))
    assert ReadOptions.of(recorded) == opts
    assert set(recorded) <= set(RECORDED_READ_OPTIONS)


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_calibrate_then_detect_when_a_joint_ends_still(tmp_path: Path, suffix: str) -> None:
    """The config `calibrate` writes for a log whose held-back part has a joint standing
    still (no relative fit error there: TOML cannot hold the null) is one `detect` takes."""
    repo = Path(__file__).resolve().parents[1]
    free = repo / "sample_logs" / "csv" / "assist_free_triangle.csv.gz"
    robot = free.with_name("assist_free_triangle.robot.json")
    log = read_log(free, robot=read_robot(robot))
    k = int(0.7 * log.n_samples)  # the last 30 % (the held-back part): elbow stands still
    rng = np.random.default_rng(0)
    changes: dict[str, Any] = {}
    for name in ("position", "position_ref", "velocity", "velocity_ref", "acceleration_ref",
                 "torque", "current", "torque_model", "torque_ext"):
        a = getattr(log, name)
        if a is None:
            continue
        a = np.array(a)
        if name in ("velocity", "velocity_ref", "acceleration_ref"):
            a[k:, 1] = 0.0
        elif name in ("torque", "current", "torque_model", "torque_ext"):
            a[k:, 1] = a[k, 1] + 0.01 * rng.standard_normal(log.n_samples - k)
        else:
            a[k:, 1] = a[k, 1]
        changes[name] = a
    still = tmp_path / "still_end.csv"
    write_log(dataclasses.replace(log, **changes), still)
    config = tmp_path / f"cfg{suffix}"
    r = CliRunner().invoke(main, ["calibrate", str(still), "--robot", str(robot),
                                  "-o", str(config)])
    assert r.exit_code == 0, r.output
    assert "still in the held-back part" in r.stdout
    contacts = repo / "sample_logs" / "csv" / "assist_impacts.csv.gz"
    r = CliRunner().invoke(main, ["detect", str(contacts), "--config", str(config),
                                  "-o", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "out" / "assist_impacts.timeline.json").is_file()
