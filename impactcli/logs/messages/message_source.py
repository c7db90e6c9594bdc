"""Message sources: an MCAP file and a ROS bag seen the same way (topics, types, raw messages).

A :class:`MessageSource` lists its topics with their message type and encoding (``cdr``:
ROS 2; ``ros1``: ROS 1; ``json``); the messages of a block come as :class:`TopicData` —
file order, log and publish times [ns], and each message's bytes in :class:`Batch` es —, so
the vectorised JointState decoder of :mod:`impactcli.logs.messages.ros2_cdr` reads MCAP and rosbag2
alike. :meth:`MessageSource.decode_all` decodes messages of any type with the definitions
stored in the file (rosbags' ``Typestore``: ``ros2msg``/``ros1msg``, ``ros2idl``; types a
definition refers to but does not carry come from rosbags' latest ROS 2 store) or
``json.loads``. rosbags' deserialiser is used because it accepts ROS 1 field names (such as
``tau_J``) that ``mcap_ros2``'s refuses; it is called on the message body directly, so
trailing CDR padding (docs/formats.md, "MCAP") is ignored. Fields are read in bulk where
the layout allows (:mod:`impactcli.logs.messages.field_read`), checked against this decoder.

Sources: :class:`~impactcli.logs.messages.mcap.McapSource` and
:class:`~impactcli.logs.messages.bags.BagSource` (rosbags' ``AnyReader``).
"""

from __future__ import annotations

import json
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import LogFormatError

JOINT_STATE = "sensor_msgs/msg/JointState"
JOINT_SAMPLE = "impactcli/JointSample"


@dataclass
class Batch:
    """Messages of one channel found in one block (an MCAP chunk, records between
    chunks, bag messages).

    Attributes:
        buf: (B,) uint8, the bytes the messages are in.
        data_off: (n,) int64 offsets of each message's data in ``buf``.
        data_len: (n,) int64 data lengths [bytes].
        log_time, publish_time: (n,) int64 [ns].
        order: (n,) int64 index of each message in file order (over all channels).
    """

    buf: np.ndarray
    data_off: np.ndarray
    data_len: np.ndarray
    log_time: np.ndarray
    publish_time: np.ndarray
    order: np.ndarray


@dataclass
class TopicData:
    """The raw messages of one topic.

    Attributes:
        topic: topic name.
        msgtype: message type (``pkg/msg/Name`` for ROS; the schema name for JSON).
        encoding: ``cdr``, ``ros1`` or ``json``.
        batches: the bytes and times, possibly in several batches.
        first: the topic's messages before these (errors name a message by its number in
            the topic: ``first`` + its index here).
        log_time, publish_time: (n,) int64 [ns] in file order.
    """

    topic: str
    msgtype: str
    encoding: str
    batches: list[Batch]
    first: int = 0
    log_time: np.ndarray = field(init=False)
    publish_time: np.ndarray = field(init=False)
    _where: list[tuple[int, int]] = field(init=False, repr=False)
    _idx: list[np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        orders = (np.concatenate([b.order for b in self.batches]) if self.batches
                  else np.zeros(0, np.int64))
        srt = np.sort(orders)
        n = srt.shape[0]
        self.log_time = np.zeros(n, np.int64)
        self.publish_time = np.zeros(n, np.int64)
        self._idx = []
        for b in self.batches:
            idx = np.searchsorted(srt, b.order)
            self.log_time[idx] = b.log_time
            self.publish_time[idx] = b.publish_time
            self._idx.append(idx)
        self._where = []  # message → (batch, index in it), made when first asked for

    @property
    def n(self) -> int:
        """Number of messages."""
        return int(self.log_time.shape[0])

    def data(self, i: int) -> bytes:
        """The bytes of message ``i`` (file order within the topic)."""
        if not self._where and self.n:
            loc = [(0, 0)] * self.n
            for bi, idx in enumerate(self._idx):
                for k, j in enumerate(idx.tolist()):
                    loc[j] = (bi, k)
            self._where = loc
        bi, k = self._where[i]
        b = self.batches[bi]
        o, ln = int(b.data_off[k]), int(b.data_len[k])
        return b.buf[o : o + ln].tobytes()


def normalize_type(name: str) -> str:
    """``sensor_msgs/JointState`` → ``sensor_msgs/msg/JointState`` (ROS names; others kept)."""
    parts = name.split("/")
    if len(parts) == 2 and parts[0] and parts[1]:
        return f"{parts[0]}/msg/{parts[1]}"
    return name


def _missing_refs(typs: dict[str, Any]) -> set[str]:
    out = set()
    for _consts, fields in typs.values():
        for _n, (node, detail) in fields:
            elem_node, elem = detail[0] if node in (3, 4) else (node, detail)
            if elem_node == 2 and elem not in typs:
                out.add(elem)
    return out


def build_typestore(defs: list[tuple[str, str, str]], where: str) -> Any:
    """A rosbags Typestore holding the types of ``defs`` ((type name, schema encoding, text)).

    Encodings: ``ros2msg``/``ros1msg`` (concatenated ``MSG:`` definitions), ``ros2idl``.
    Types referred to but not defined come from rosbags' latest ROS 2 store.

    Raises:
        LogFormatError: a definition that does not parse.
    """
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    typs: dict[str, Any] = {}
    for name, enc, text in defs:
        try:
            if enc in ("ros2msg", "ros1msg", "msg"):
                typs.update(get_types_from_msg(text, normalize_type(name)))
            elif enc in ("ros2idl", "idl"):
                sep = "=" * 80 + "\n"
                parts = ([p.split("\n", 1)[1] for p in text.split(sep)[1:]]
                         if text.startswith(f"{sep}IDL: ") else [text])
                for p in parts:
                    typs.update(get_types_from_idl(p))
        except Exception as err:  # rosbags' parser errors have no common base
            first = (str(err).splitlines() or [type(err).__name__])[0]
            raise LogFormatError(f"{where}: cannot parse the definition of {name}: "
                                 f"{first}") from err
    missing = _missing_refs(typs)
    if missing:
        base = get_typestore(Stores.LATEST).fielddefs
        while missing:
            add = {m: base[m] for m in missing if m in base}
            if not add:
                break
            typs.update(add)
            missing = _missing_refs(typs)
    store = get_typestore(Stores.EMPTY)
    store.register(typs)
    return store


class MessageSource:
    """Topics, types and raw messages of a log file (see the module docstring).

    Attributes:
        where: the log's path for messages.
        kind: ``mcap``, ``rosbag2`` or ``rosbag1``.
        repairs: repairs made while opening (a truncated MCAP).
    """

    where: str = ""
    kind: str = ""

    def __init__(self) -> None:
        self.repairs: list[str] = []
        self._store: Any = None
        self._decoders: dict[str, Any] = {}

    def topics(self) -> dict[str, tuple[str, str]]:
        """Topic → (message type, encoding)."""
        raise NotImplementedError

    def load(self, topics: Collection[str]) -> dict[str, TopicData]:
        """The raw messages of ``topics`` (each must be in :meth:`topics`)."""
        raise NotImplementedError

    def definitions(self) -> list[tuple[str, str, str]]:
        """(type name, schema encoding, definition text) of the types in the file."""
        raise NotImplementedError

    def typestore(self) -> Any:
        """A rosbags Typestore of the file's types (built once)."""
        if self._store is None:
            self._store = build_typestore(self.definitions(), self.where)
        return self._store

    def fielddefs(self, msgtype: str) -> dict[str, Any]:
        """rosbags field definitions of every type; raises LogFormatError when ``msgtype``
        is not defined in the file."""
        defs = self.typestore().fielddefs
        if msgtype not in defs:
            raise LogFormatError(f"{self.where}: the file holds no definition of {msgtype}")
        return dict(defs)

    def decode_all(self, td: TopicData, rows: np.ndarray | None = None) -> list[Any]:
        """Every message of ``td`` decoded (file order), or those numbered ``rows``.

        Raises:
            LogFormatError: a message that does not decode, naming topic and message.
        """
        which = range(td.n) if rows is None else [int(i) for i in rows]
        if td.encoding == "json":
            out = []
            for i in which:
                try:
                    out.append(json.loads(td.data(i)))
                except ValueError as err:
                    raise LogFormatError(f"{self.where}: topic {td.topic!r}, message "
                                         f"{i + td.first}: bad JSON: {err}") from None
            return out
        if td.encoding not in ("cdr", "ros1"):
            raise LogFormatError(f"{self.where}: topic {td.topic!r}: message encoding "
                                 f"{td.encoding!r} cannot be decoded (cdr, ros1 or json)")
        store = self.typestore()
        if td.msgtype not in store.fielddefs:
            raise LogFormatError(f"{self.where}: topic {td.topic!r}: the file holds no "
                                 f"definition of {td.msgtype}")
        md = store.get_msgdef(td.msgtype)
        out = []
        for i in which:
            raw = td.data(i)
            try:
                if td.encoding == "ros1":
                    msg, _ = md.deserialize_ros1(raw, 0, md.cls, store)
                else:
                    if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
                        raise ValueError(f"unknown CDR encapsulation {raw[:2].hex()}")
                    fn = md.deserialize_cdr_le if raw[1] else md.deserialize_cdr_be
                    msg, _ = fn(memoryview(raw)[4:], 0, md.cls, store)
            except Exception as err:  # struct/unicode/value errors of generated code
                raise LogFormatError(f"{self.where}: topic {td.topic!r}, message "
                                     f"{i + td.first}: not a {td.msgtype}: {err}") from None
            out.append(msg)
        return out


def header_stamps(msgs: list[Any]) -> np.ndarray | None:
    """(n,) int64 header stamps [ns] of decoded messages, or None when they have no header
    (ROS ``header.stamp``; JSON ``stamp_ns`` or ``header.stamp.{sec,nanosec}``)."""
    if not msgs:
        return None
    out = np.zeros(len(msgs), np.int64)
    for i, m in enumerate(msgs):
        if isinstance(m, dict):
            if "stamp_ns" in m:
                out[i] = int(m["stamp_ns"] or 0)
                continue
            st = (m.get("header") or {}).get("stamp") if isinstance(m.get("header"), dict) \
                else None
            if not isinstance(st, dict):
                return None
            out[i] = int(st.get("sec", 0)) * 10**9 + int(st.get("nanosec", 0))
            continue
        h = getattr(m, "header", None)
        st = getattr(h, "stamp", None)
        if st is None or not hasattr(st, "sec"):
            return None
        out[i] = int(st.sec) * 10**9 + int(st.nanosec)
    return out
