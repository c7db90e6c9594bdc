"""Writing robot logs: :func:`write_log` by suffix, every file atomically.

- canonical wide CSV (:func:`write_csv`): ``time`` in seconds with 9 decimals (exact in
  ns), then per joint ``<joint>.position``, ``<joint>.torque`` and the optional signals,
  values in shortest round-trip (repr) precision — reading the file back gives the same
  RobotLog;
- MCAP: :func:`write_mcap_json` (one JSON JointSample per sample, every signal) and
  :func:`write_mcap_ros2` (JointState state, ``_ref``, ``_model`` and ``_ext`` topics:
  :func:`jointstate_topics`);
- ROS bags through ``rosbags``, with the same JointState topics: :func:`write_rosbag2`
  (a ``.db3`` file, or a folder, optionally split into several files) and
  :func:`write_rosbag1`.
"""

from __future__ import annotations

import gzip
import itertools
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LogFormatError, OutputError
from ..files import temporary_folder, whole
from ..sample_channels import CHANNEL_NAMES, CONTROLLER_CHANNELS
from ..types import RobotLog
from .messages.message_source import JOINT_SAMPLE
from .messages.ros2_cdr import JOINT_STATE, JOINT_STATE_DEF
from .paths import ROSBAG2_METADATA, log_suffix

JSON_TOPIC = "/joint_samples"
ROS2_TOPIC = "/joint_states"
ROS2_REF_TOPIC = "/joint_states_ref"


def write_log(log: RobotLog, path: str | os.PathLike[str], *, mcap_encoding: str = "json") -> None:
    """Write ``log`` by suffix, atomically (never a half-written file).

    Args:
        log: the log.
        path: ``.csv`` / ``.csv.gz`` (canonical wide CSV, exact round trip), ``.mcap``,
            ``.db3`` (rosbag2 SQLite file) or ``.bag`` (ROS 1); the bags hold JointState
            topics as ``mcap_encoding="ros2"`` does (a rosbag2 folder: :func:`write_rosbag2`).
        mcap_encoding: ``json`` (impactcli joint samples on ``/joint_samples``) or ``ros2``
            (JointState on ``/joint_states``, effort = torque; reference on
            ``/joint_states_ref``; effort = torque_model on ``/joint_states_model`` and
            torque_ext on ``/joint_states_ext``).

    Raises:
        LogFormatError: unknown suffix or encoding.
    """
    p = Path(path)
    suffix = log_suffix(p)
    if suffix == ".db3":
        write_rosbag2(log, p)
    elif suffix == ".bag":
        write_rosbag1(log, p)
    elif suffix in (".csv", ".csv.gz"):
        write_csv(log, p)
    elif suffix == ".mcap":
        if mcap_encoding == "json":
            write_mcap_json(log, p)
        elif mcap_encoding == "ros2":
            write_mcap_ros2(log, p)
        else:
            raise LogFormatError(f"{p}: unknown MCAP encoding {mcap_encoding!r} (json or ros2)")
    else:
        raise LogFormatError(
            f"{p}: cannot write this format (use .csv, .csv.gz, .mcap, .db3 or .bag)")


# --------------------------------------------------------------------------------- CSV
def ns_to_decimal_text(t_ns: np.ndarray) -> Any:
    """int64 ns → pyarrow strings of seconds with 9 decimals (exact), e.g. ``-0.500000000``."""
    import pyarrow as pa
    import pyarrow.compute as pc

    t = np.asarray(t_ns, dtype=np.int64)
    sec, frac = np.divmod(np.abs(t), 10**9)
    txt = pc.binary_join_element_wise(
        pc.cast(pa.array(sec), pa.string()),
        pc.utf8_lpad(pc.cast(pa.array(frac), pa.string()), 9, "0"),
        ".",
    )
    if np.any(t < 0):
        txt = pc.if_else(pa.array(t < 0), pc.binary_join_element_wise("-", txt, ""), txt)
    return txt


def canonical_columns(log: RobotLog) -> list[tuple[str, np.ndarray]]:
    """The canonical CSV's value columns: (name, (N,) values) in file order."""
    out: list[tuple[str, np.ndarray]] = []
    for j, name in enumerate(log.joint_names):
        for sig in CHANNEL_NAMES:
            arr = getattr(log, sig)
            if arr is not None and log.has_channel(sig)[j]:
                out.append((f"{name}.{sig}", arr[:, j]))
    return out


def write_csv(log: RobotLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as canonical wide CSV (``.csv``, or gzip for ``.csv.gz``), atomically.

    ``time`` holds seconds on the log's own clock with 9 decimals (exact ns); values are
    written in shortest round-trip precision, so :func:`read_log` returns the same arrays.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from ..files import atomic_output

    cols = canonical_columns(log)
    table = pa.table(
        {"time": ns_to_decimal_text(np.asarray(log.t_ns))}
        | {name: pa.array(np.ascontiguousarray(v)) for name, v in cols}
    )
    head = ",".join(["time"] + [c for c, _ in cols]) + "\n"
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")
    p = Path(path)
    with atomic_output(p, "wb") as f:
        if p.name.lower().endswith(".gz"):
            with gzip.GzipFile(fileobj=f, mode="wb", compresslevel=1, mtime=0) as gz:
                gz.write(head.encode())
                pacsv.write_csv(table, gz, opts)
        else:
            f.write(head.encode())
            pacsv.write_csv(table, f, opts)


# -------------------------------------------------------------------------------- MCAP
def _check_times(log: RobotLog, path: Path) -> None:
    if log.t_ns[0] < 0:
        raise LogFormatError(
            f"{path}: MCAP cannot hold negative times (first sample {log.t_ns[0]} ns)"
        )


def _nan_as_none(a: np.ndarray) -> list[Any]:
    obj = a.astype(object)
    obj[np.isnan(a)] = None
    out: list[Any] = obj.tolist()
    return out


def write_mcap_json(log: RobotLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as MCAP with impactcli JSON joint samples on ``/joint_samples`` (atomic).

    One message per sample: ``stamp_ns`` and, per signal the log has, a list over ``name``.
    log_time = publish_time = stamp_ns = t_ns.
    """
    from mcap.writer import CompressionType, Writer

    from ..files import atomic_output
    from ..schema import schema_dir

    p = Path(path)
    _check_times(log, p)
    sigs = [(s, getattr(log, s)) for s in CHANNEL_NAMES if getattr(log, s) is not None]
    names = list(log.joint_names)
    lists = {s: _nan_as_none(a) if s in CONTROLLER_CHANNELS else a.tolist() for s, a in sigs}
    with atomic_output(p, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="", library="impactcli")
        sid = w.register_schema(
            name=JOINT_SAMPLE, encoding="jsonschema",
            data=(schema_dir() / "joint_sample.schema.json").read_bytes(),
        )
        cid = w.register_channel(topic=JSON_TOPIC, message_encoding="json", schema_id=sid)
        for i, t in enumerate(log.t_ns.tolist()):
            msg: dict[str, Any] = {"stamp_ns": t, "name": names}
            for s, _ in sigs:
                msg[s] = lists[s][i]
            w.add_message(cid, log_time=t, publish_time=t, sequence=i,
                          data=json.dumps(msg, separators=(",", ":")).encode())
        w.finish()  # type: ignore[no-untyped-call]


def write_mcap_ros2(
    log: RobotLog, path: str | os.PathLike[str], *, pad: int = 0, chunk_size: int = 1 << 20,
) -> None:
    """Write ``log`` as MCAP with ROS 2 JointState (CDR) on ``/joint_states`` (atomic).

    effort = torque; velocity filled when the log has it. At the same times: the reference
    (``position_ref``, ``velocity_ref``) on ``/joint_states_ref``, ``torque_model`` as the
    effort of ``/joint_states_model`` and ``torque_ext`` as the effort of
    ``/joint_states_ext`` — each naming only the joints that log the channel. Header stamp =
    log_time = publish_time = t_ns. ``pad`` appends that many zero bytes to every message
    (as some real recorders do; for tests); ``chunk_size`` [bytes] is the MCAP chunk size.
    Current and acceleration_ref are not carried.
    """
    from ..files import atomic_output

    p = Path(path)
    _check_times(log, p)
    topics = jointstate_topics(log, ROS2_TOPIC)
    zeros = b"\x00" * pad
    with atomic_output(p, "wb") as f:
        w, sid = ros2_writer(f, chunk_size)
        cids = [w.register_channel(topic=name, message_encoding="cdr", schema_id=sid)
                for name, _ in topics]
        for i, t in enumerate(log.t_ns.tolist()):
            # companions first: a state sample never precedes its reference at equal times
            for cid, (_, rows) in reversed(list(zip(cids, topics, strict=True))):
                w.add_message(cid, log_time=t, publish_time=t, sequence=i,
                              data=rows[i].tobytes() + zeros)
        w.finish()  # type: ignore[no-untyped-call]


def ros2_writer(f: Any, chunk_size: int = 1 << 20) -> tuple[Any, int]:
    """An MCAP writer started on the open binary file ``f`` (zstd chunks of
    ``chunk_size`` bytes, ``ros2`` profile) and the id of its JointState schema
    (``ros2msg``): register channels on it, add messages, ``finish()``."""
    from mcap.writer import CompressionType, Writer

    w = Writer(f, compression=CompressionType.ZSTD, chunk_size=chunk_size)
    w.start(profile="ros2", library="impactcli")
    sid = w.register_schema(name=JOINT_STATE, encoding="ros2msg",
                            data=JOINT_STATE_DEF.encode())
    return w, sid


def jointstate_topics(log: RobotLog, state_topic: str) -> list[tuple[str, np.ndarray]]:
    """The JointState topics that carry ``log`` and their CDR messages, state topic first.

    Returns:
        ``[(topic, (N, L) uint8 rows of CDR bytes)]``: ``state_topic`` (position, velocity,
        effort = torque), ``<state_topic>_ref`` (position_ref, velocity_ref) when the log has
        a reference, ``_model`` / ``_ext`` (effort = torque_model / torque_ext, naming only
        the joints that log it) when the log has the channel.
    """
    from .messages.ros2_cdr import encode_jointstates

    out = [(state_topic, encode_jointstates(log.t_ns, log.joint_names, log.position,
                                            log.velocity, log.torque))]
    if log.position_ref is not None:
        out.append((f"{state_topic}_ref", encode_jointstates(
            log.t_ns, log.joint_names, log.position_ref, log.velocity_ref, None)))
    for suffix, sig in (("_model", "torque_model"), ("_ext", "torque_ext")):
        arr = getattr(log, sig)
        if arr is None:
            continue
        has = log.has_channel(sig)
        names = [nm for nm, h in zip(log.joint_names, has, strict=True) if h]
        out.append((f"{state_topic}{suffix}",
                    encode_jointstates(log.t_ns, names, None, None, arr[:, has])))
    return out


# ---------------------------------------------------------------------------- ROS bags
def _check_ros_times(log: RobotLog, path: Path) -> None:
    if log.t_ns[0] < 0:
        raise LogFormatError(f"{path}: ROS bags cannot hold negative times "
                             f"(first sample {log.t_ns[0]} ns)")


def ros2_typestore() -> Any:
    """rosbags' ROS 2 Humble types (the JointState the bags are written with)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _write_rosbag2_folder(log: RobotLog, folder: Path, parts: list[slice],
                          storage: str) -> None:
    """Write the rosbag2 folder ``folder`` (must not exist) in ``len(parts)`` files."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from ruamel.yaml import YAML

    topics = jointstate_topics(log, ROS2_TOPIC)
    store = ros2_typestore()
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    t = log.t_ns.tolist()
    with temporary_folder(".rosbag2-", folder.parent) as tmp:
        metas = []
        subs = []
        for k, part in enumerate(parts):
            # rosbags names the storage file after its folder: <name>_<k>.db3 as ros2 bag does
            sub = tmp / f"part{k}" / f"{folder.name}_{k}"
            subs.append(sub)
            with Writer(sub, version=9, storage_plugin=plugin) as w:
                conns = [w.add_connection(name, JOINT_STATE, typestore=store)
                         for name, _ in topics]
                for i in range(len(t))[part]:
                    # companions first: a state sample never precedes its reference
                    for c, (_, rows) in reversed(list(zip(conns, topics, strict=True))):
                        w.write(c, t[i], rows[i].tobytes())
            yaml = YAML(typ="safe")
            metas.append(yaml.load((sub / ROSBAG2_METADATA).read_text()))
        out = tmp / "bag"
        out.mkdir()
        info = metas[0]["rosbag2_bagfile_information"]
        if len(parts) == 1:
            for f in subs[0].iterdir():
                f.rename(out / f.name)
        else:
            files, rel = [], []
            counts: dict[str, int] = {}
            for k, m in enumerate(metas):
                mi = m["rosbag2_bagfile_information"]
                src = subs[k] / mi["relative_file_paths"][0]
                name = src.name
                src.rename(out / name)
                rel.append(name)
                fi = dict(mi["files"][0], path=name)
                files.append(fi)
                for tw in mi["topics_with_message_count"]:
                    nm = tw["topic_metadata"]["name"]
                    counts[nm] = counts.get(nm, 0) + int(tw["message_count"])
            last = metas[-1]["rosbag2_bagfile_information"]
            start = info["starting_time"]["nanoseconds_since_epoch"]
            end = (last["starting_time"]["nanoseconds_since_epoch"]
                   + last["duration"]["nanoseconds"])
            info = dict(info, relative_file_paths=rel, files=files,
                        message_count=sum(counts.values()),
                        duration={"nanoseconds": end - start})
            info["topics_with_message_count"] = [
                dict(tw, message_count=counts[tw["topic_metadata"]["name"]])
                for tw in info["topics_with_message_count"]
            ]
            yaml = YAML(typ="safe")
            yaml.default_flow_style = False
            with open(out / ROSBAG2_METADATA, "w", encoding="utf-8") as mf:
                yaml.dump({"rosbag2_bagfile_information": info}, mf)
        out.rename(folder)


def write_rosbag2(log: RobotLog, path: str | os.PathLike[str], *, split: int = 1,
                  storage: str = "sqlite3") -> None:
    """Write ``log`` as a rosbag2 (JointState topics, see the module docstring).

    Args:
        log: the log (times ≥ 0).
        path: a ``.db3`` file (written whole or not at all), or a folder that does not exist
            yet (made whole by a rename: a rosbag2 folder is never overwritten).
        split: number of files the folder is split into (consecutive samples; ``.db3``
            needs 1).
        storage: ``sqlite3`` (``.db3`` files) or ``mcap`` (folder only).

    Raises:
        LogFormatError: negative times, bad ``split`` or ``storage``.
        OutputError: the folder exists, or cannot be written.
    """
    p = Path(path)
    _check_ros_times(log, p)
    n = log.n_samples
    if storage not in ("sqlite3", "mcap"):
        raise LogFormatError(f"{p}: unknown rosbag2 storage {storage!r} (sqlite3 or mcap)")
    if not 1 <= split <= n:
        raise LogFormatError(f"{p}: cannot split {n} samples into {split} files")
    edges = np.linspace(0, n, split + 1).round().astype(int).tolist()
    parts = [slice(a, b) for a, b in itertools.pairwise(edges)]
    if p.suffix.lower() == ".db3":
        if split != 1 or storage != "sqlite3":
            raise LogFormatError(f"{p}: a .db3 file is one SQLite file: write a folder to "
                                 "split or to use MCAP storage")
        from ..files import atomic_output

        # atomic_output checks the target; the .db3 is copied onto it
        with atomic_output(p, "wb") as f, temporary_folder(".rosbag2-", p.parent) as tmp:
            _write_rosbag2_folder(log, tmp / "bag", parts, storage)
            db = next((tmp / "bag").glob("*.db3"))
            with open(db, "rb") as src:
                shutil.copyfileobj(src, f, 1 << 20)
        return
    if p.exists():
        raise OutputError(f"cannot write {p}: it exists (a rosbag2 folder is never overwritten)")
    p.parent.mkdir(parents=True, exist_ok=True)
    _write_rosbag2_folder(log, p, parts, storage)


def write_rosbag1(log: RobotLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as a ROS 1 ``.bag`` (atomically): ``sensor_msgs/JointState`` on
    ``/joint_states`` and the ``_ref``, ``_model``, ``_ext`` companions, as
    :func:`write_rosbag2`; header stamps = bag times = ``t_ns`` (≥ 0, below 2³² s)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from ..files import atomic_output
    p = Path(path)
    _check_ros_times(log, p)
    if log.t_ns[-1] >= 2**32 * 10**9:
        raise LogFormatError(f"{p}: ROS 1 times end in 2106 (last sample {log.t_ns[-1]} ns)")
    store = get_typestore(Stores.ROS1_NOETIC)
    name = "sensor_msgs/msg/JointState"
    JointState = store.types[name]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    empty = np.zeros(0)
    topics: list[tuple[str, list[str], list[np.ndarray | None]]] = [
        (ROS2_TOPIC, list(log.joint_names), [log.position, log.velocity, log.torque])]
    if log.position_ref is not None:
        topics.append((f"{ROS2_TOPIC}_ref", list(log.joint_names),
                       [log.position_ref, log.velocity_ref, None]))
    for suffix, sig in (("_model", "torque_model"), ("_ext", "torque_ext")):
        arr = getattr(log, sig)
        if arr is not None:
            has = log.has_channel(sig)
            topics.append((f"{ROS2_TOPIC}{suffix}",
                           [nm for nm, h in zip(log.joint_names, has, strict=True) if h],
                           [None, None, np.ascontiguousarray(arr[:, has])]))
    with atomic_output(p, "wb") as f:
        with whole():  # a free name: rosbags' writer makes the file itself
            fd, tmpname = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp.bag",
                                           dir=p.parent)
            os.close(fd)
            tmp = Path(tmpname)
            tmp.unlink()
        try:
            with Writer(tmp) as w:
                conns = [w.add_connection(tn, name, typestore=store) for tn, _, _ in topics]
                for i, t in enumerate(log.t_ns.tolist()):
                    sec, nsec = divmod(t, 10**9)
                    for c, (_, names, arrs) in reversed(list(zip(conns, topics, strict=True))):
                        msg = JointState(
                            header=Header(seq=i, stamp=Time(sec=sec, nanosec=nsec), frame_id=""),
                            name=names,
                            position=empty if arrs[0] is None else arrs[0][i],
                            velocity=empty if arrs[1] is None else arrs[1][i],
                            effort=empty if arrs[2] is None else arrs[2][i],
                        )
                        w.write(c, t, store.serialize_ros1(msg, name))
            with open(tmp, "rb") as src:
                shutil.copyfileobj(src, f, 1 << 20)
        finally:
            tmp.unlink(missing_ok=True)
