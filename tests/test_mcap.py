"""MCAP readers: bulk decoder vs the official one, padding, truncation, reference alignment,
time sources, topic choice, names matched on every message."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from impactcli.errors import ImpactWarning, LogFormatError
from impactcli.logs import read_log, write_log
from impactcli.logs.messages.mcap import scan_mcap
from impactcli.logs.messages.ros2_cdr import (
    JOINT_STATE,
    JOINT_STATE_DEF,
    decode_topic,
    decode_topic_official,
    encode_jointstates,
    parse_jointstate,
)
from impactcli.logs.write import write_mcap_ros2
from impactcli.types import RobotLog

from .conftest import make_log

NAMES = ("j1", "j2", "j3")


def _official_file(path: Path, msgs: list[dict[str, Any]], compression: CompressionType,
                   chunk_size: int = 2048) -> None:
    """Write JointState messages with the official mcap_ros2 writer.

    Each msg: topic, t (log time), pub, stamp, name, position, velocity, effort.
    """
    from mcap_ros2.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=compression)
        schema = w.register_msgdef(JOINT_STATE, JOINT_STATE_DEF)
        for m in msgs:
            sec, nsec = divmod(m["stamp"], 10**9)
            w.write_message(m.get("topic", "/joint_states"), schema, {
                "header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": m.get("frame", "")},
                "name": list(m["name"]), "position": list(m["position"]),
                "velocity": list(m["velocity"]), "effort": list(m["effort"]),
            }, log_time=m["t"], publish_time=m.get("pub", m["t"]))
        w.finish()


def _random_msgs(
    n: int, seed: int = 0, shuffle: bool = True
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    t = 1_000_000_000 + np.arange(n, dtype=np.int64) * 2_000_000
    truth = {s: rng.normal(size=(n, 3)) for s in ("position", "velocity", "effort")}
    truth["position"] = np.cumsum(0.002 * truth["velocity"], axis=0)  # moves at its velocity
    msgs = []
    for i in range(n):
        order = rng.permutation(3) if shuffle and i % 7 == 3 else np.arange(3)
        frame = "base_link" if shuffle and i % 11 == 5 else ""  # another size, another group
        msgs.append({
            "t": int(t[i]), "pub": int(t[i]) + 17, "stamp": int(t[i]) - 1000, "frame": frame,
            "name": [NAMES[k] for k in order],
            **{s: truth[s][i, order].tolist() for s in truth},
        })
    truth["t"] = t
    return msgs, truth


@pytest.mark.parametrize("compression", [CompressionType.ZSTD, CompressionType.LZ4,
                                         CompressionType.NONE], ids=["zstd", "lz4", "none"])
def test_bulk_decoder_equals_official_reader(tmp_path: Path, compression: CompressionType) -> None:
    msgs, truth = _random_msgs(600)
    path = tmp_path / "a.mcap"
    _official_file(path, msgs, compression)
    scan = scan_mcap(path)
    assert not scan.truncated
    ours = decode_topic(scan, scan.topics()["/joint_states"], str(path), "/joint_states")
    official = decode_topic_official(path, "/joint_states", str(path))
    for attr in ("log_time", "publish_time", "header", "position", "velocity", "effort",
                 "has_joints", "has_velocity", "has_effort"):
        np.testing.assert_array_equal(getattr(ours, attr), getattr(official, attr), err_msg=attr)
    np.testing.assert_array_equal(ours.position, truth["position"])  # names matched per message
    log = read_log(path)
    assert log.joint_names == NAMES and log.source.time_source == "header"
    np.testing.assert_array_equal(log.t_ns, truth["t"] - 1000)
    np.testing.assert_array_equal(log.torque, truth["effort"])
    np.testing.assert_array_equal(log.velocity, truth["velocity"])


def test_encoder_matches_official_serializer(tmp_path: Path) -> None:
    msgs, _ = _random_msgs(5, shuffle=False)
    msgs[2]["velocity"] = []  # an empty sequence: no alignment padding
    path = tmp_path / "o.mcap"
    _official_file(path, msgs, CompressionType.NONE)
    scan = scan_mcap(path)
    (b,) = scan.batches[next(iter(scan.batches))]
    for i, m in enumerate(msgs):
        o, ln = int(b.data_off[i]), int(b.data_len[i])
        vel = np.array([m["velocity"]]) if m["velocity"] else None
        mine = encode_jointstates(np.array([m["stamp"]]), m["name"], np.array([m["position"]]),
                                  vel, np.array([m["effort"]]))[0].tobytes()
        assert mine == b.buf[o : o + ln].tobytes(), i
        assert parse_jointstate(mine).names == NAMES


def _log(n: int = 300, ref: bool = False) -> RobotLog:
    return make_log(n=n, joints=NAMES, with_ref=ref, seed=2)


@pytest.mark.parametrize("pad", [1, 3, 8])
def test_trailing_cdr_padding_is_tolerated(tmp_path: Path, pad: int) -> None:
    log = _log(ref=True)
    path = tmp_path / "p.mcap"
    write_mcap_ros2(log, path, pad=pad)
    back = read_log(path)
    np.testing.assert_array_equal(back.position, log.position)
    np.testing.assert_array_equal(back.torque, log.torque)
    np.testing.assert_array_equal(back.position_ref, log.position_ref)
    official = decode_topic_official(path, "/joint_states", str(path))
    np.testing.assert_array_equal(official.effort, log.torque)


def test_truncated_file_yields_what_was_recorded_with_a_warning(tmp_path: Path) -> None:
    log = _log(n=3000)
    path = tmp_path / "full.mcap"
    write_mcap_ros2(log, path, chunk_size=8192)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.warns(ImpactWarning, match="truncated"):
        back = read_log(cut)
    k = back.n_samples
    assert 100 < k < 3000
    np.testing.assert_array_equal(back.t_ns, log.t_ns[:k])
    np.testing.assert_array_equal(back.position, log.position[:k])
    assert any("truncated" in r for r in back.source.repairs)
    assert back.source.truncated and not read_log(path).source.truncated
    # the official reader recovers the same messages before the cut
    official = decode_topic_official(cut, "/joint_states", str(cut))
    assert official.position.shape[0] == k


def test_truncated_before_any_message_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "full.mcap"
    write_mcap_ros2(_log(n=3000), path)  # one big chunk
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:3000])
    with pytest.raises(LogFormatError, match=r"cut.mcap: corrupt or empty MCAP: truncated"):
        read_log(cut)


def test_non_chunked_file(tmp_path: Path) -> None:
    log = _log(n=50)
    path = tmp_path / "nc.mcap"
    rows = encode_jointstates(log.t_ns, NAMES, log.position, None, log.torque)
    with open(path, "wb") as f:
        w = McapWriter(f, use_chunking=False)
        w.start()
        sid = w.register_schema(JOINT_STATE, "ros2msg", JOINT_STATE_DEF.encode())
        cid = w.register_channel("/joint_states", "cdr", sid)
        for i, t in enumerate(log.t_ns.tolist()):
            w.add_message(cid, log_time=t + 5, publish_time=t + 5, data=rows[i].tobytes())
        w.finish()
    back = read_log(path)
    np.testing.assert_array_equal(back.position, log.position)
    assert back.velocity is None
    # stamps are zero for the first sample (t=0): header is not usable, log time is used
    assert back.source.time_source == "log"
    np.testing.assert_array_equal(back.t_ns, log.t_ns + 5)


def test_reference_sample_and_hold_is_causal(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    n = 200
    t = 10_000_000 + np.arange(n, dtype=np.int64) * 1_000_000  # 1 kHz state
    tr = 12_500_000 + np.arange(50, dtype=np.int64) * 4_000_000  # 250 Hz reference, late start
    q = np.cumsum(rng.normal(scale=1e-3, size=(n, 3)), axis=0)  # a motion, not noise
    qr = rng.normal(size=(50, 3))
    msgs = [{"t": int(t[i]), "stamp": int(t[i]), "name": list(NAMES), "position": q[i].tolist(),
             "velocity": [], "effort": q[i].tolist()} for i in range(n)]
    msgs += [{"t": int(tr[k]), "stamp": int(tr[k]), "topic": "/cmd", "name": list(NAMES[::-1]),
              "position": qr[k, ::-1].tolist(), "velocity": [], "effort": []} for k in range(50)]
    msgs.sort(key=lambda m: m["t"])
    path = tmp_path / "r.mcap"
    _official_file(path, msgs, CompressionType.ZSTD)
    with pytest.warns(ImpactWarning, match="dropped the first 3 state sample"):
        log = read_log(path, reference_topic="/cmd")
    assert log.t_ns[0] == t[3]
    for i in range(log.n_samples):
        k = int(np.flatnonzero(tr <= log.t_ns[i])[-1])  # latest reference at or before
        np.testing.assert_array_equal(log.position_ref[i], qr[k])
    assert log.velocity_ref is None
    with pytest.raises(LogFormatError, match="reference topic '/nope' not found"):
        read_log(path, reference_topic="/nope")


def test_time_sources(tmp_path: Path) -> None:
    msgs, truth = _random_msgs(40, shuffle=False)
    path = tmp_path / "ts.mcap"
    _official_file(path, msgs, CompressionType.ZSTD)
    t = truth["t"]
    assert read_log(path).t_ns.tolist() == (t - 1000).tolist()
    for src, want in (("log", t), ("publish", t + 17), ("header", t - 1000)):
        log = read_log(path, time_source=src)
        assert log.source.time_source == src
        np.testing.assert_array_equal(log.t_ns, want)
    for m in msgs:
        m["stamp"] = 0
    _official_file(path, msgs, CompressionType.ZSTD)
    assert read_log(path).source.time_source == "log"
    with pytest.raises(LogFormatError, match="header stamp is zero"):
        read_log(path, time_source="header")


def test_topic_choice(tmp_path: Path) -> None:
    msgs, _ = _random_msgs(20, shuffle=False)
    for i, m in enumerate(msgs):
        m["topic"] = "/left/joint_states" if i % 2 else "/right/joint_states"
    path = tmp_path / "two.mcap"
    _official_file(path, msgs, CompressionType.ZSTD)
    with pytest.raises(LogFormatError, match=r"pass --topic \(topics: /left/joint_states, "
                                             r"/right/joint_states\)"):
        read_log(path)
    log = read_log(path, topic="/left/joint_states")
    assert log.n_samples == 10
    assert log.source.ignored_channels == ("/right/joint_states",)


def test_message_missing_a_joint_is_an_error(tmp_path: Path) -> None:
    msgs, _ = _random_msgs(20, shuffle=False)
    for s in ("name", "position", "velocity", "effort"):
        msgs[9][s] = msgs[9][s][:2]
    path = tmp_path / "m.mcap"
    _official_file(path, msgs, CompressionType.ZSTD)
    with pytest.raises(LogFormatError, match="message 9 lacks some of the joints"):
        read_log(path)


def test_message_without_effort_is_an_error(tmp_path: Path) -> None:
    msgs, _ = _random_msgs(20, shuffle=False)
    msgs[4]["effort"] = []
    path = tmp_path / "e.mcap"
    _official_file(path, msgs, CompressionType.ZSTD)
    with pytest.raises(LogFormatError, match=r"message 4 has no effort \(torque\)"):
        read_log(path)


def test_json_samples_matched_by_name_and_stamp_fallback(tmp_path: Path) -> None:
    import json

    rng = np.random.default_rng(8)
    q, tau = np.cumsum(rng.normal(scale=1e-3, size=(30, 3)), axis=0), rng.normal(size=(30, 3))
    path = tmp_path / "j.mcap"
    with open(path, "wb") as f:
        w = McapWriter(f)
        w.start()
        sid = w.register_schema("impactcli/JointSample", "jsonschema", b"{}")
        cid = w.register_channel("/joint_samples", "json", sid)
        for i in range(30):
            order = [2, 0, 1] if i % 2 else [0, 1, 2]
            msg = {"name": [NAMES[k] for k in order], "position": q[i, order].tolist(),
                   "torque": tau[i, order].tolist()}
            w.add_message(cid, log_time=1000 + i * 10, publish_time=0,
                          data=json.dumps(msg).encode())
        w.finish()
    log = read_log(path)
    assert log.source.format == "mcap-json" and log.source.time_source == "log"
    np.testing.assert_array_equal(log.position, q)
    np.testing.assert_array_equal(log.torque, tau)
    np.testing.assert_array_equal(log.t_ns, 1000 + np.arange(30) * 10)


def test_duplicate_messages_are_dropped_with_a_warning(tmp_path: Path) -> None:
    msgs, truth = _random_msgs(30, shuffle=False)
    msgs.insert(11, dict(msgs[10]))
    path = tmp_path / "d.mcap"
    _official_file(path, msgs, CompressionType.ZSTD)
    with pytest.warns(ImpactWarning, match="dropped 1 exact duplicate"):
        log = read_log(path)
    np.testing.assert_array_equal(log.position, truth["position"])


def test_write_log_ros2_readable_by_official_reader(tmp_path: Path) -> None:
    log = _log(ref=True)
    path = tmp_path / "w.mcap"
    write_log(log, path, mcap_encoding="ros2")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ref = decode_topic_official(path, "/joint_states_ref", str(path))
    np.testing.assert_array_equal(ref.position, log.position_ref)
    np.testing.assert_array_equal(ref.velocity, log.velocity_ref)


def test_unsupported_files_fall_back_to_the_official_reader(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import impactcli.logs.messages.mcap as scan_mod

    log = _log(ref=True)
    path = tmp_path / "f.mcap"
    write_log(log, path, mcap_encoding="ros2")

    def unsupported(kind: str, data: bytes, size: int) -> bytes:
        raise scan_mod.UnsupportedMcap(f"compression {kind!r}")

    monkeypatch.setattr(scan_mod, "_decompress", unsupported)
    back = read_log(path)  # default reference topic <topic>_ref, as with the scanner
    np.testing.assert_array_equal(back.t_ns, log.t_ns)
    np.testing.assert_array_equal(back.torque, log.torque)
    np.testing.assert_array_equal(back.position_ref, log.position_ref)
