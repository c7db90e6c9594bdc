"""The one reader (impactcli.logs.reader) on MCAP, ROS bags, .npz and URLs: for every chunk
size the chunks are the same arrays, and the scan's clock, gaps and screens are the whole
log's (``_assert_same`` of tests/test_reader_csv.py); the variants (stamps out of order,
topics far apart in the file) read through the same pass, each message decoded once."""

from __future__ import annotations

import json
import warnings
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from impactcli.errors import ChannelMapError, ImpactWarning, LogFormatError
from impactcli.logs import npz as stream_npz
from impactcli.logs import read_log, write_log
from impactcli.logs.messages.ros2_cdr import encode_jointstates
from impactcli.logs.reader import iter_chunks, scan_log
from impactcli.logs.write import ros2_writer
from impactcli.types import LogSource, RobotLog

from .stream_invariants import assert_streams_exactly, read_error

JOINTS = ("a", "b", "c")
N = 2000


def _signals(n: int = N, seed: int = 0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Jittery 1 kHz times with a 40 ms gap, and position, velocity, torque, reference and
    controller values for 3 joints."""
    rng = np.random.default_rng(seed)
    t = 10**9 + np.cumsum(rng.integers(990_000, 1_010_000, n))
    t[n // 3:] += 40_000_000
    q = np.cumsum(rng.normal(0, 1e-3, (n, 3)), axis=0)
    return t, {"position": q, "velocity": rng.normal(0, 1, (n, 3)),
               "torque": rng.normal(0, 5, (n, 3)), "position_ref": q + 1e-4,
               "velocity_ref": rng.normal(0, 1, (n, 3)),
               "torque_model": rng.normal(0, 5, (n, 3)), "torque_ext": rng.normal(0, 1, (n, 3))}


def _write_ros2(path: Path, msgs: list[tuple[str, int, bytes]], chunk_size: int = 4096) -> Path:
    """An MCAP of CDR JointState messages ``(topic, log time, bytes)`` in this file order
    (small chunks: the state and its companions fall across many)."""
    with open(path, "wb") as f:
        w, sid = ros2_writer(f, chunk_size)
        cids: dict[str, int] = {}
        for k, (topic, lt, data) in enumerate(msgs):
            if topic not in cids:
                cids[topic] = w.register_channel(topic=topic, message_encoding="cdr",
                                                 schema_id=sid)
            w.add_message(cids[topic], log_time=lt, publish_time=lt, sequence=k, data=data)
        w.finish()  # type: ignore[no-untyped-call]
    return path


def _topics(t: np.ndarray, v: dict[str, np.ndarray], log_t: np.ndarray | None = None,
            ref_from: int = 0, model_from: int = 0, ref_delay: int = 0,
            header: np.ndarray | None = None) -> list[tuple[str, int, bytes]]:
    """State, _ref and _model messages; the reference starts at sample ``ref_from`` and is
    written ``ref_delay`` samples late; ``header`` the stamps (default ``t``), ``log_t``
    the log times (default ``t``)."""
    hdr = t if header is None else header
    lt = t if log_t is None else log_t
    state = encode_jointstates(hdr, JOINTS, v["position"], v["velocity"], v["torque"])
    ref = encode_jointstates(hdr, JOINTS, v["position_ref"], v["velocity_ref"], None)
    model = encode_jointstates(hdr, JOINTS[:2], None, None, v["torque_model"][:, :2])
    out: list[tuple[str, int, bytes]] = []
    late: list[tuple[str, int, bytes]] = []
    for i in range(t.size):
        if i >= model_from:
            out.append(("/joint_states_model", int(lt[i]), model[i].tobytes()))
        if i >= ref_from:
            late.append(("/joint_states_ref", int(lt[i]), ref[i].tobytes()))
        if ref_delay == 0:
            out += late
            late = []
        out.append(("/joint_states", int(lt[i]), state[i].tobytes()))
        if ref_delay and len(late) > ref_delay:
            out.append(late.pop(0))
    return out + late


def _repairs(v: dict[str, np.ndarray], t: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
    """Short runs of NaN and exact duplicate samples all over the log (they fall across
    chunk boundaries)."""
    v = {s: a.copy() for s, a in v.items()}
    for k, start in enumerate(range(37, t.size - 20, 173)):
        v["position" if k % 2 else "torque_model"][start:start + 1 + k % 5, k % 2] = np.nan
    dup = np.arange(t.size)
    dup = np.sort(np.concatenate((dup, np.arange(50, t.size, 311))))
    return t[dup], {s: a[dup] for s, a in v.items()}


# ------------------------------------------------------------------------------- MCAP
def test_the_shipped_mcap_logs() -> None:
    root = Path(__file__).resolve().parents[1] / "sample_logs" / "mcap"
    for name in ("assist_impacts", "heavy_free_p2p"):  # ROS 2 with companions; JSON
        assert_streams_exactly(root / f"{name}.mcap", chunks=(7, 1000))


def test_ros2_with_companions_repairs_and_a_gap(tmp_path: Path) -> None:
    t, v = _signals()
    t, v = _repairs(v, t)
    scan = assert_streams_exactly(_write_ros2(tmp_path / "r.mcap", _topics(t, v)),
                                  chunks=(1, 7, 1000))
    assert scan.source.repairs and scan.gaps.size == 1
    assert scan.source.time_source == "header" and scan.source.format == "mcap-ros2"


def test_companions_starting_late_and_written_late(tmp_path: Path) -> None:
    t, v = _signals()
    for kw in ({"ref_from": 30, "model_from": 55}, {"ref_delay": 9}, {"ref_delay": 700}):
        msgs = _topics(t, v, **kw)
        scan = assert_streams_exactly(_write_ros2(tmp_path / "late.mcap", msgs),
                                      chunks=(1, 7, 1000))
        if "ref_from" in kw:
            assert any("dropped the first 55 state" in r for r in scan.source.repairs)


def test_header_stamps_against_log_times(tmp_path: Path) -> None:
    t, v = _signals()
    rng = np.random.default_rng(3)
    log_t = t + rng.integers(0, 3_000_000, t.size)  # received late, out of stamp order
    scan = assert_streams_exactly(_write_ros2(tmp_path / "h.mcap", _topics(t, v, log_t=log_t)),
                                  chunks=(7, 1000))
    assert scan.source.time_source == "header"
    hdr = t.copy()
    hdr[500] = 0  # a zero stamp: log time for all
    msgs = _topics(t, v, log_t=np.sort(log_t), header=hdr)
    scan = assert_streams_exactly(_write_ros2(tmp_path / "z.mcap", msgs), chunks=(7, 1000))
    assert scan.source.time_source == "log"
    assert_streams_exactly(tmp_path / "h.mcap", chunks=(1000,), time_source="log")


def test_json_samples_with_repairs(tmp_path: Path) -> None:
    from mcap.writer import CompressionType, Writer

    t, v = _signals()
    t, v = _repairs(v, t)
    path = tmp_path / "j.mcap"
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, chunk_size=4096)
        w.start(profile="", library="test")
        sid = w.register_schema(name="impactcli/JointSample", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/joint_samples", message_encoding="json", schema_id=sid)
        for i, ti in enumerate(t.tolist()):
            msg = {"stamp_ns": ti, "name": list(JOINTS),
                   **{s: v[s][i].tolist() for s in ("position", "torque", "velocity",
                                                     "position_ref", "torque_model")}}
            w.add_message(cid, log_time=ti, publish_time=ti, sequence=i,
                          data=json.dumps(msg).encode())
        w.finish()  # type: ignore[no-untyped-call]
    scan = assert_streams_exactly(path, chunks=(1, 1000))
    assert scan.source.format == "mcap-json" and scan.source.repairs


def test_the_chunk_walker_equals_the_official_reader(tmp_path: Path) -> None:
    """Chunks of interleaved topics (record sizes repeating with a period, or not: the
    duplicates and the late reference break it) are located as the official reader reads
    them."""
    from impactcli.logs.messages.mcap import scan_mcap, scan_mcap_official

    t, v = _signals(600)
    for k, msgs in enumerate((_topics(t, v), _topics(*_repairs(v, t)),
                              _topics(t, v, ref_delay=5, model_from=7))):
        path = _write_ros2(tmp_path / f"w{k}.mcap", msgs, chunk_size=1500 + 977 * k)
        ours, theirs = scan_mcap(path), scan_mcap_official(path)
        assert ours.n_messages == theirs.n_messages == len(msgs)
        for cid, (topic, _, _) in theirs.channels.items():
            want = theirs.batches[cid][0]
            got = ours.batches[cid]
            order = np.concatenate([b.order for b in got])
            assert np.array_equal(np.sort(order), want.order), topic
            data = [bytes(b.buf[o:o + n]) for b in got
                    for o, n in zip(b.data_off, b.data_len, strict=True)]
            times = np.concatenate([b.log_time for b in got])
            rank = np.argsort(order, kind="stable")
            assert [data[i] for i in rank] == [bytes(want.buf[o:o + n]) for o, n in zip(
                want.data_off, want.data_len, strict=True)], topic
            assert np.array_equal(times[rank], want.log_time), topic


def test_a_truncated_mcap(tmp_path: Path) -> None:
    t, v = _signals()
    full = _write_ros2(tmp_path / "full.mcap", _topics(t, v)).read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full[: len(full) * 2 // 3])
    scan = assert_streams_exactly(cut, chunks=(7, 1000))
    assert "truncated" in scan.source.repairs[0]


def test_state_stamps_out_of_order_are_sorted(tmp_path: Path) -> None:
    """Two state messages out of stamp order in the file: the samples are in time order (a
    stable sort of the stamps), the repairs name the messages by their place in the file,
    and the companions are held onto the sorted samples."""
    t, v = _signals()
    msgs = _topics(t, v)
    state = [m for m in msgs if m[0] == "/joint_states"]
    swapped = msgs[:]
    i, k = swapped.index(state[100]), swapped.index(state[101])
    swapped[i], swapped[k] = swapped[k], swapped[i]
    path = _write_ros2(tmp_path / "s.mcap", swapped)
    scan = assert_streams_exactly(path, chunks=(7, 1000))
    log = read_log(path)
    assert np.array_equal(log.t_ns, t) and np.array_equal(log.position, v["position"])
    assert np.array_equal(log.position_ref, v["position_ref"]) and scan.n_samples == t.size
    v2 = dict(v, torque=v["torque"].copy())
    v2["torque"][400:410, 1] = np.nan  # a run of 10, named by its first message in the file
    swapped2 = _topics(t, v2)
    st2 = [m for m in swapped2 if m[0] == "/joint_states"]
    i, k = swapped2.index(st2[100]), swapped2.index(st2[101])
    swapped2[i], swapped2[k] = swapped2[k], swapped2[i]
    assert "message 400 of '/joint_states'" in read_error(_write_ros2(tmp_path / "r.mcap",
                                                                      swapped2))


def test_topics_far_apart_in_the_file(tmp_path: Path) -> None:
    """A reference written 700 samples late (its messages far from the state's in the
    file): each topic is read from its own spill, file order does not matter."""
    t, v = _signals()
    path = _write_ros2(tmp_path / "late.mcap", _topics(t, v, ref_delay=700))
    assert_streams_exactly(path, chunks=(1000,))
    log = read_log(path)
    assert np.array_equal(log.position_ref, v["position_ref"])


def test_a_message_decoded_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Reading an MCAP (the scan, then every chunk collected) decompresses each MCAP chunk
    once and decodes each topic's messages of a chunk once: one decode call per chunk
    and topic read."""
    from impactcli.logs.messages import mcap as mcap_scan
    from impactcli.logs.messages import message_read as messages

    t, v = _signals()
    path = _write_ros2(tmp_path / "r.mcap", _topics(t, v), chunk_size=8192)
    chunks = mcap_scan.scan_mcap(path)
    per_topic: dict[int, set[int]] = {}
    for cid, batches in chunks.batches.items():
        per_topic[cid] = {id(b.buf) for b in batches}
    n_chunks = len({k for s in per_topic.values() for k in s})
    decompressed: list[int] = []
    decoded: list[str] = []
    real_dec, real_decode = mcap_scan._decompress, messages.decode_batches
    monkeypatch.setattr(mcap_scan, "_decompress",
                        lambda *a: decompressed.append(1) or real_dec(*a))
    monkeypatch.setattr(messages, "decode_batches",
                        lambda batches, where, topic, *a: decoded.append(topic) or real_decode(
                            batches, where, topic, *a))
    log = read_log(path)
    assert log.n_samples == t.size and n_chunks > 10
    assert len(decompressed) == n_chunks
    assert len(decoded) == sum(len(s) for s in per_topic.values())


def test_bad_message_logs_fail_as_read_log_does(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap at all")
    assert "bad magic" in read_error(bad)
    t, v = _signals()
    path = _write_ros2(tmp_path / "r.mcap", _topics(t, v))
    assert "not found" in read_error(path, topic="/nope")
    t2, v2 = _signals()
    v2["torque"][300:310, 1] = np.nan  # a run of 10: an error, named as read_log names it
    path = _write_ros2(tmp_path / "run.mcap", _topics(t2, v2))
    assert "run of 10 non-finite" in read_error(path)


# ------------------------------------------------------------- MCAP through channel maps
def test_a_custom_state_message_through_a_map(tmp_path: Path) -> None:
    from .message_logs import (
        ARM,
        ARM_DEF,
        arm_map,
        arm_messages,
        fixture_log,
        store_with,
        write_mcap,
    )

    log = fixture_log(n=700, acc_ref=True)
    store = store_with((ARM, ARM_DEF))
    p = tmp_path / "arm.mcap"  # the log time lags the header stamp
    write_mcap(p, [("/arm/state", ARM, "ros2msg", "cdr",
                    [(t + 700_000, t + 600_000, m) for t, m in
                     zip(log.t_ns.tolist(), arm_messages(store, log), strict=True)])])
    cmap = arm_map(tmp_path / "arm.yaml")
    for tsrc in (None, "log", "publish"):
        opts = {} if tsrc is None else {"time_source": tsrc}
        scan = assert_streams_exactly(p, chunks=(1, 7, 1000), channel_map=cmap, **opts)
    assert scan.source.format == "mcap-ros2"
    cut = tmp_path / "cut.mcap"  # no summary section: its topics from a pass of their own
    cut.write_bytes(p.read_bytes()[: p.stat().st_size * 3 // 5])
    scan = assert_streams_exactly(cut, chunks=(7, 1000), channel_map=cmap)
    assert "truncated" in scan.source.repairs[0]
    bad = tmp_path / "bad.yaml"  # a field the message does not have: the map's error
    bad.write_text("format: messages\njoints:\n  - {name: shoulder, position: /arm/state/nope}\n")
    with pytest.raises(ChannelMapError) as whole:
        read_log(p, channel_map=bad)
    with pytest.raises(ChannelMapError) as scanned:
        scan_log(p, channel_map=bad)
    assert str(scanned.value) == str(whole.value)


def test_maps_over_jointstate_and_other_topics(tmp_path: Path) -> None:
    from .message_logs import JOINTS as FJ
    from .message_logs import fixture_log, two_topics

    p = two_topics(tmp_path, ["wrist", "gripper", "elbow_joint", "shoulder"])[0]
    m = tmp_path / "ext.json"
    ext = "/external_torque/effort"
    m.write_text(json.dumps({"format": "messages", "joints": [
        {"name": "shoulder", "torque_ext": {"field": ext}},
        {"name": "elbow", "torque_ext": {"field": ext, "joint": "elbow_joint", "scale": -2.0,
                                         "offset": 0.5}},
        {"name": "wrist", "torque_ext": {"field": ext}}]}))
    for tsrc in (None, "log"):
        opts = {} if tsrc is None else {"time_source": tsrc}
        assert_streams_exactly(p, chunks=(1, 7, 1000), channel_map=m, **opts)
    log = fixture_log(n=300)  # a map signal replaces the companion topic's
    write_log(log, tmp_path / "s.mcap", mcap_encoding="ros2")
    m2 = tmp_path / "m2.yaml"
    m2.write_text("format: messages\njoints:\n" + "".join(
        f"  - {{name: {j}, velocity_ref: {{field: /joint_states/velocity}}, "
        f"torque_ext: {{field: /joint_states_model/effort, scale: -1}}}}\n" for j in FJ[::-1]))
    scan = assert_streams_exactly(tmp_path / "s.mcap", chunks=(7, 1000), channel_map=m2)
    assert scan.source.ignored_channels == ("/joint_states_ext",)


def test_a_map_over_json_messages(tmp_path: Path) -> None:
    from impactcli.logs.messages.ros2_cdr import JOINT_STATE as JS

    from .message_logs import JOINTS as FJ
    from .message_logs import fixture_log, jointstates, write_mcap

    log = fixture_log(n=400)
    rows = [(ti, ti, json.dumps({"stamp_ns": ti, "ext": log.torque_ext[i].tolist(),
                                 "model": {"name": list(FJ[::-1]),
                                           "effort": log.torque_model[i, ::-1].tolist()}}
                                ).replace("NaN", "null").encode())
            for i, ti in enumerate(log.t_ns.tolist())]
    p = tmp_path / "j.mcap"
    write_mcap(p, [("/joint_states", JS, "ros2msg", "cdr",
                    jointstates(log.t_ns, list(FJ), log.position, log.torque)),
                   ("/controller", "my/Controller", "jsonschema", "json", rows)])
    m = tmp_path / "m.yaml"
    m.write_text("format: messages\njoints:\n" + "".join(
        f"  - {{name: {j}, torque_ext: '/controller/ext[{k}]', "
        f"torque_model: {{field: /controller/model/effort}}}}\n" for k, j in enumerate(FJ)))
    assert_streams_exactly(p, chunks=(1, 1000), channel_map=m)


# ------------------------------------------------------------------------------- bags
def _log(n: int = N) -> RobotLog:
    t, v = _signals(n)
    return RobotLog(t_ns=t, joint_names=JOINTS, source=LogSource(path="x", sha256="",
                                                                 format="csv"), **v)


def test_bags(tmp_path: Path) -> None:
    from impactcli.logs.write import write_rosbag2

    log = _log()
    for name in ("a.db3", "a.bag"):
        write_log(log, tmp_path / name)
        assert_streams_exactly(tmp_path / name, chunks=(1, 7, 1000))
    write_rosbag2(log, tmp_path / "folder", split=3)
    assert_streams_exactly(tmp_path / "folder", chunks=(7, 1000))
    write_rosbag2(log, tmp_path / "mcap_folder", split=2, storage="mcap")
    assert_streams_exactly(tmp_path / "mcap_folder", chunks=(7, 1000))


# -------------------------------------------------------------------------------- npz
@pytest.fixture
def _small_npz_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(stream_npz, "BLOCK_ROWS", 97)


def _npz_map(tmp_path: Path, **time: Any) -> Path:
    cmap = tmp_path / "npz.json"
    cmap.write_text(json.dumps({
        "format": "npz",
        "time": {"column": "t", "unit": "s", **time},
        "joints": [{"name": j, "position": {"column": "q", "index": k},
                    "torque": {"column": f"tau_{j}", "scale": 2.0},
                    "torque_model": {"column": "tm", "index": k}}
                   for k, j in enumerate(JOINTS)]}))
    return cmap


@pytest.mark.usefixtures("_small_npz_blocks")
def test_npz_plain_and_compressed(tmp_path: Path) -> None:
    t, v = _signals()
    t, v = _repairs(v, t)
    arrays = {"t": t * 1e-9, "q": v["position"], "tm": v["torque_model"],
              "extra": np.zeros(3), **{f"tau_{j}": v["torque"][:, k]
                                       for k, j in enumerate(JOINTS)}}
    cmap = _npz_map(tmp_path)
    for save, name in ((np.savez, "a.npz"), (np.savez_compressed, "c.npz")):
        save(tmp_path / name, **arrays)
        scan = assert_streams_exactly(tmp_path / name, chunks=(1, 7, 1000), channel_map=cmap)
        assert scan.source.format == "npz" and scan.source.repairs
    np.savez(tmp_path / "i.npz", **{**arrays, "t": (t // 1000).astype(np.int32)})
    assert_streams_exactly(tmp_path / "i.npz", chunks=(7,), channel_map=_npz_map(
        tmp_path, unit="us", start_at_zero=True))


def test_npz_errors_are_read_logs(tmp_path: Path) -> None:
    t, v = _signals()
    cmap = _npz_map(tmp_path)
    np.savez(tmp_path / "short.npz", t=t * 1e-9, q=v["position"][:-1], tm=v["torque_model"],
             **{f"tau_{j}": v["torque"][:, k] for k, j in enumerate(JOINTS)})
    assert "mismatched channel lengths" in read_error(tmp_path / "short.npz",
                                                      channel_map=cmap)
    np.savez(tmp_path / "ms.npz", t=t * 1e-6, q=v["position"], tm=v["torque_model"],
             **{f"tau_{j}": v["torque"][:, k] for k, j in enumerate(JOINTS)})
    assert "implied sample rate" in read_error(tmp_path / "ms.npz", channel_map=cmap)


def test_a_corrupt_npz_member_is_one_line_exit_3(tmp_path: Path) -> None:
    """A compressed member whose bytes are damaged (bad CRC): ``detect`` says so in one
    line naming the file and the array, exit 3, no traceback, no output."""
    from click.testing import CliRunner

    from impactcli.cli import main

    t, v = _signals()
    path = tmp_path / "bad.npz"
    np.savez_compressed(path, t=t * 1e-9, q=v["position"], tm=v["torque_model"],
                        **{f"tau_{j}": v["torque"][:, k] for k, j in enumerate(JOINTS)})
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo("tm.npy")
    body = info.header_offset + 30 + len(info.filename) + len(info.extra) + 200
    raw[body:body + 64] = bytes(64)
    path.write_bytes(bytes(raw))
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(path), "--channel-map",
                                  str(_npz_map(tmp_path)), "-o", str(out)])
    assert r.exit_code == 3, r.output
    assert "Traceback" not in r.output and "internal error" not in r.output
    line = [x for x in r.output.splitlines() if "error" in x]
    assert len(line) == 1 and "bad.npz" in line[0] and "'tm'" in line[0], r.output
    assert not list(out.glob("*")) if out.exists() else True


# ------------------------------------------------------------------------------- URLs
def test_urls_stream_a_local_copy(tmp_path: Path) -> None:
    import fsspec

    t, v = _signals()
    path = _write_ros2(tmp_path / "r.mcap", _topics(t, v))
    url = path.as_uri()
    scan = assert_streams_exactly(path, chunks=(1000,))
    with fsspec.open("memory://logs/r.mcap", "wb") as f:
        f.write(path.read_bytes())
    for u in (url, "memory://logs/r.mcap"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ImpactWarning)
            log = read_log(u)
            s = scan_log(u)
        assert s.source.path == u == log.source.path
        assert s.source.sha256 == scan.source.sha256
        got = list(iter_chunks(u, s, 333))
        assert np.array_equal(np.concatenate([c.torque for c in got]), log.torque)
        ps = s.reader._pass  # type: ignore[union-attr]
        assert ps is not None
        local = ps.layout.path
        assert local.exists()
        s.close()
        assert local.exists() == (u == url)  # a download is deleted with the scan
    with fsspec.open("memory://logs/bad.mcap", "wb") as f:
        f.write(b"garbage")
    with pytest.raises(LogFormatError) as whole:
        read_log("memory://logs/bad.mcap")
    with pytest.raises(LogFormatError) as scanned:
        scan_log("memory://logs/bad.mcap")
    assert str(scanned.value) == str(whole.value) and "memory://logs/bad.mcap" in str(
        whole.value)
    with pytest.raises(LogFormatError, match="not found"):
        scan_log("memory://logs/none.mcap")


# ------------------------------------------------------------------- without the cache
def test_a_full_disk_reads_the_file_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                          ) -> None:
    """Without the scan's cache of the repaired rows every pass reads the archive again,
    and a message log's spill of decoded messages is kept in memory: the same arrays."""
    from impactcli import spill

    monkeypatch.setattr(spill, "MIN_FREE_BYTES", float("inf"))  # the caches' one policy
    monkeypatch.setattr(stream_npz, "BLOCK_ROWS", 101)
    t, v = _signals()
    t, v = _repairs(v, t)
    mcap = _write_ros2(tmp_path / "r.mcap", _topics(t, v, ref_from=20, ref_delay=3))
    arrays = {"t": t * 1e-9, "q": v["position"], "tm": v["torque_model"],
              **{f"tau_{j}": v["torque"][:, k] for k, j in enumerate(JOINTS)}}
    np.savez_compressed(tmp_path / "a.npz", **arrays)
    for path, opts in ((mcap, {}), (tmp_path / "a.npz", {"channel_map": _npz_map(tmp_path)})):
        scan = assert_streams_exactly(path, chunks=(7, 1000), **opts)
        ps = scan.reader._pass  # type: ignore[union-attr]
        assert ps.cache is None
        assert all(not r.spill.on_disk for r in getattr(ps.layout, "readers", {}).values())
