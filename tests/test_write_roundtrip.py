"""One RobotLog written as canonical CSV, MCAP-JSON and MCAP-ROS2 reads back the same."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impactcli.logs import log_stem, read_log, write_log
from impactcli.types import RobotLog

from .conftest import make_log


def _log(t0_ns: int = 0) -> RobotLog:
    base = make_log(n=400, joints=("shoulder", "elbow", "wrist"), seed=3)
    rng = np.random.default_rng(4)
    # jittered times on an epoch clock: exercises exact ns handling
    t = t0_ns + np.cumsum(rng.integers(3_900_000, 4_100_000, base.n_samples)).astype(np.int64)
    return RobotLog(
        t_ns=t, joint_names=base.joint_names, position=base.position, torque=base.torque,
        velocity=rng.normal(size=base.position.shape), current=rng.normal(size=base.position.shape),
        position_ref=base.position_ref, velocity_ref=base.velocity_ref,
        acceleration_ref=base.acceleration_ref,
    )


# (file name, mcap encoding, signals the format carries besides t/position/torque, format)
VARIANTS = [
    ("log.csv", "json", ("velocity", "current", "position_ref", "velocity_ref",
                         "acceleration_ref"), "csv"),
    ("log.csv.gz", "json", ("velocity", "current", "position_ref", "velocity_ref",
                            "acceleration_ref"), "csv"),
    ("log.mcap", "json", ("velocity", "current", "position_ref", "velocity_ref",
                          "acceleration_ref"), "mcap-json"),
    ("log.mcap", "ros2", ("velocity", "position_ref", "velocity_ref"), "mcap-ros2"),
]


@pytest.mark.parametrize("t0_ns", [0, 1_700_000_000_123_456_789])
@pytest.mark.parametrize(("name", "enc", "carried", "fmt"), VARIANTS,
                         ids=["csv", "csv.gz", "mcap-json", "mcap-ros2"])
def test_same_log_every_format(tmp_path: Path, name: str, enc: str, carried: tuple[str, ...],
                               fmt: str, t0_ns: int) -> None:
    log = _log(t0_ns)
    path = tmp_path / name
    write_log(log, path, mcap_encoding=enc)
    back = read_log(path)
    assert back.source.format == fmt
    assert back.source.torque_source == "torque"
    assert back.source.repairs == ()
    assert back.joint_names == log.joint_names
    np.testing.assert_array_equal(back.t_ns, log.t_ns)
    np.testing.assert_array_equal(back.position, log.position)
    np.testing.assert_array_equal(back.torque, log.torque)
    for sig in ("velocity", "current", "position_ref", "velocity_ref", "acceleration_ref"):
        if sig in carried:
            np.testing.assert_array_equal(getattr(back, sig), getattr(log, sig), err_msg=sig)
        else:
            assert getattr(back, sig) is None, sig
    assert len(back.source.sha256) == 64


def test_write_is_atomic_and_leaves_no_partial_file(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    import mcap.writer

    log = _log()
    path = tmp_path / "x.mcap"
    write_log(log, path, mcap_encoding="ros2")
    before = path.read_bytes()

    def boom(self: object) -> None:
        raise RuntimeError("disk full")

    monkeypatch.setattr(mcap.writer.Writer, "finish", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        write_log(log.slice(0, 10), path, mcap_encoding="json")
    assert path.read_bytes() == before  # untouched
    assert [p.name for p in tmp_path.iterdir()] == ["x.mcap"]  # no temporary left


@pytest.mark.parametrize(("name", "stem"), [
    ("a/b/run1.csv", "run1"), ("run1.csv.gz", "run1"), ("x.y.mcap", "x.y"),
    ("m.npz", "m"), ("RUN.CSV.GZ", "RUN"), ("notes.txt", "notes.txt"),
])
def test_log_stem(name: str, stem: str) -> None:
    assert log_stem(name) == stem


def test_csv_time_is_exact_in_ns(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text(
        "time,j.position,j.torque\n"
        "1700000000.000000001,0.5,1\n"
        "1700000000.001000002,0.6,2\n"
        "1700000000.0020000035,0.7,3\n"
    )
    log = read_log(path)
    assert log.t_ns.tolist() == [1700000000000000001, 1700000000001000002, 1700000000002000003]
    path.write_text("time_ns,j.position,j.torque\n5,0.5,1\n4000005,0.6,2\n")
    assert read_log(path).t_ns.tolist() == [5, 4_000_005]
    path.write_text("__time,j.position,j.torque\n1.5e0,0.5,1\n1.504,0.6,2\n")
    assert read_log(path).t_ns.tolist() == [1_500_000_000, 1_504_000_000]
