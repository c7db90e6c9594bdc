"""The Rerun recording of a run (``detect --rerun``, ``view``), written from its chunks.

:class:`RerunWriter` is a run's ``on_chunk``: per chunk it appends what the recording
plots (the signals, the positions, the decisions) to the temporary store
(:class:`impactcli.spill.ColumnFiles`); once the answer is known (events, incidents,
warm-up) :meth:`RerunWriter.write` reads it back chunk by chunk and writes the recording,
atomically. Memory: one chunk's rows and the
open bucket of each series' envelope. The recording holds, per joint, the statistics
against their thresholds, the residuals and positions, the detectors' markers and state
lanes, the events, incidents and warm-up (docs/formats.md, "Rerun recording"; its look:
:mod:`impactcli.outputs.rerun_blueprint`):

- long series as the documented min/max envelope (:mod:`impactcli.outputs.decimate`,
  buckets counted from the log's first sample) plus every sample within
  ``event_window_s`` of an event, and the first and the last sample;
- the markers by the same rule over the fired samples (counted in a first pass over the
  decisions), every lane transition at full rate.

``rerun`` (rerun-sdk) is imported inside the functions, never at module import.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import OutputError
from ..files import discard, finish_output, part_path, prepare_output, whole
from ..spill import ColumnFiles
from ..types import DETECTORS
from . import rerun_blueprint as look
from .decimate import DEFAULT_EVENT_WINDOW_S, DEFAULT_MAX_POINTS, EnvelopeStream

#: (plot, its series as (name, spill column)) — the reference position, when logged, is
#: drawn first, under the measured one; the loading plot gets the constant vL.
PLOTS: dict[str, list[tuple[str, str]]] = {
    "rms": [("residual RMS", "residual_rms"), ("threshold v_stat+v_rms", "threshold")],
    "loading": [("loading statistic", "loading_statistic")],
    "residual": [("residual r", "residual"), ("filtered residual", "filtered_residual")],
    "position": [("measured", "position")],
}
#: The signals a recording plots (of :data:`impactcli.types.SIGNAL_NAMES`).
PLOTTED = ("residual_rms", "threshold", "loading_statistic", "residual", "filtered_residual")


def spill_columns(joints: tuple[str, ...], t_ns: np.ndarray, signals: dict[str, np.ndarray],
                  decisions: dict[str, np.ndarray], position: np.ndarray,
                  position_ref: np.ndarray | None) -> dict[str, np.ndarray]:
    """One chunk's columns of the spill file: ``t_ns``, and per joint the plotted signals,
    the position (and reference) and the 0/1 decisions."""
    cols: dict[str, np.ndarray] = {"t_ns": np.asarray(t_ns, dtype=np.int64)}
    for j, joint in enumerate(joints):
        for name in PLOTTED:
            cols[f"{joint}.{name}"] = np.asarray(signals[name][:, j], dtype=np.float64)
        cols[f"{joint}.position"] = np.asarray(position[:, j], dtype=np.float64)
        if position_ref is not None:
            cols[f"{joint}.position_ref"] = np.asarray(position_ref[:, j], dtype=np.float64)
        for det in DETECTORS:
            cols[f"{joint}.{det}"] = np.asarray(decisions[det][:, j], dtype=bool)
    return cols


class RerunWriter:
    """The Rerun recording of a run, fed its chunks (module docstring).

    Call it with each chunk of the replay (``joints``, ``t_ns``, ``signals``, ``decisions``,
    ``position``, ``position_ref``), in time order; then :meth:`write`; :meth:`close` (or
    the ``with`` block) removes the spill file.
    """

    def __init__(self) -> None:
        self.spill = ColumnFiles("impactcli-rrd-")

    def __call__(self, chunk: Any) -> None:
        """One chunk of the replay."""
        if len(chunk.t_ns):
            self.spill.append(spill_columns(chunk.joints, chunk.t_ns, chunk.signals,
                                            chunk.decisions, chunk.position,
                                            chunk.position_ref))

    def write(self, result: Any, path: str | os.PathLike[str], *,
              max_points: int = DEFAULT_MAX_POINTS,
              event_window_s: float = DEFAULT_EVENT_WINDOW_S,
              recording_id: str | None = None) -> None:
        """Write the recording of ``result`` (the run the chunks came from) to ``path``.

        Args:
            max_points: per-series size above which series are decimated.
            event_window_s: full-rate window kept on each side of every event [s].
            recording_id: Rerun recording id (default: a fresh one). Pass the id of another
                recording of the same log to merge both when opened together.
        """
        write_recording(result, self.spill, path, max_points=max_points,
                        event_window_s=event_window_s, recording_id=recording_id)

    def close(self) -> None:
        """Remove the spill file."""
        self.spill.close()

    def __enter__(self) -> RerunWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_recording(result: Any, spill: ColumnFiles, path: str | os.PathLike[str], *,
                    max_points: int = DEFAULT_MAX_POINTS,
                    event_window_s: float = DEFAULT_EVENT_WINDOW_S,
                    recording_id: str | None = None) -> None:
    """The recording of ``result`` from its spill file (:class:`RerunWriter`), atomically."""
    rr = import_rerun()

    spill.finish()
    joints = tuple(result.log.joint_names)
    n = spill.rows
    t0 = int(result.log.t0_ns)
    pad = round(event_window_s * 1e9)
    # first pass: the times the events and incidents stand at, the warm-up ends, the counts
    # of fired samples
    wanted = {0} | {int(min(max(e.i_start, 0), n - 1)) for e in result.events}
    wanted |= {int(min(e.i_end, n - 1)) for e in result.events}
    for inc in result.incidents:
        wanted |= {int(min(max(inc.i_start, 0), n - 1)),
                   int(min(max(inc.i_end, inc.i_start), n - 1)) + 1}
    w_end = {j: result.warmup_per_joint_s.get(j, result.warmup_end_s) for j in joints}
    i_warm = dict.fromkeys(joints, n)
    times: dict[int, int] = {}
    fired = {(j, d): 0 for j in joints for d in DETECTORS}
    k0 = 0
    for g in spill.groups(["t_ns", *[f"{j}.{d}" for j in joints for d in DETECTORS]]):
        t = g["t_ns"]
        m = t.shape[0]
        for i in wanted:
            if k0 <= i < k0 + m:
                times[i] = int(t[i - k0])
        ts = (t - t0).astype(np.float64) * 1e-9
        for j in joints:
            if i_warm[j] == n:
                hit = np.flatnonzero(ts >= w_end[j])
                if hit.size:
                    i_warm[j] = k0 + int(hit[0])
                    times[i_warm[j]] = int(t[hit[0]])
            for d in DETECTORS:
                fired[(j, d)] += int(np.count_nonzero(g[f"{j}.{d}"]))
        k0 += m
    windows = [(times[int(min(max(e.i_start, 0), n - 1))] - pad,
                times[int(min(e.i_end, n - 1))] + pad) for e in result.events]

    def at_times(t_sel: np.ndarray) -> list[Any]:
        ts = np.asarray(t_sel, dtype=np.int64)
        return [rr.TimeColumn(look.LOG_TIMELINE, timestamp=ts.view("datetime64[ns]")),
                rr.TimeColumn(look.ELAPSED_TIMELINE, duration=(ts - t0).view("timedelta64[ns]"))]

    def at_samples(sel: Any) -> list[Any]:
        return at_times(np.array([times[int(i)] for i in np.atleast_1d(sel)], dtype=np.int64))

    has_reference = any(c.endswith(".position_ref") for c in spill.layout)
    with open_recording(path, result, has_reference, recording_id) as rec:
        _write_samples(rec, result, spill, n, has_reference, windows, fired, max_points,
                       at_times)
        for j in joints:
            write_warmup_lane(rec, j, i_warm[j], n, at_samples)
        write_events(rec, result, n, at_samples, i_warm)
        write_incidents(rec, result, n, at_samples)
        write_payload_changes(rec, result, at_times)


#: How long the Rerun SDK may take to set up, flush and close a recording's file sink [s]
#: before the writer gives up on it and says so (a sink that failed can block for good).
SINK_TIMEOUT_S = 120.0


def sink_call(fn: Callable[[], None], target: Path, what: str,
              timeout_s: float | None = None) -> None:
    """Run ``fn`` (a call into the SDK's sink) in a helper thread and wait at most
    ``timeout_s`` (default :data:`SINK_TIMEOUT_S`) for it: past that, give up —
    OutputError naming ``target`` — and leave the thread behind (a daemon). Its errors are
    raised here."""
    import threading

    if timeout_s is None:
        timeout_s = SINK_TIMEOUT_S

    failed: list[BaseException] = []

    def run() -> None:
        try:
            fn()
        except BaseException as err:
            failed.append(err)

    t = threading.Thread(target=run, name=f"impactcli-rrd-{what}", daemon=True)
    t.start()
    t.join(timeout_s)
    if t.is_alive():
        raise OutputError(f"cannot write {target}: the Rerun SDK did not {what} its file "
                          f"within {timeout_s:g} s (a full or failed disk?); given up")
    if failed:
        raise failed[0]


def sdk_write_error(target: Path, err: BaseException) -> OutputError | None:
    """The SDK's error for a file sink that could not write (``Failed to encode LogMsg:
    Failed to write: No space left on device (os error 28)``) as the one line of an output
    that cannot be written; None for any other error."""
    msg = str(err)
    if not isinstance(err, RuntimeError | OSError) or not any(
            k in msg for k in ("Failed to write", "os error", "File-writer")):
        return None
    if "Failed to write: " in msg:
        why = msg.rsplit("Failed to write: ", 1)[-1].partition(" (os error")[0].strip()
    else:  # the writer thread died and kept its reason to itself: look at the disk
        try:
            st = os.statvfs(target.parent)
            full = st.f_bavail * st.f_frsize < 1 << 20
        except (OSError, AttributeError):
            full = False
        why = (f"{'No space left on device' if full else 'the disk refused the writes'} "
               "(the Rerun SDK's file writer stopped)")
    return OutputError(f"cannot write {target}: {why}")


def import_rerun() -> Any:
    """``rerun``, its own log lines on stderr silenced (``RUST_LOG=off`` unless set): a
    failure of its file sink is told by :func:`open_recording` as one line."""
    os.environ.setdefault("RUST_LOG", "off")
    import rerun as rr

    return rr


def verify_rrd(tmp: Path) -> None:
    """A written recording before it is moved into place: the RRD header, the footer the
    SDK writes last (rerun-sdk 0.41: the manifest's offset and size, a checksum,
    ``RRF2FOOT``, a version) agreeing with the file's size, and the SDK's reader finding the
    recording in it — what the viewer needs to open it. ValueError naming what is wrong."""
    import struct
    import warnings

    import rerun as rr

    size = tmp.stat().st_size
    with open(tmp, "rb") as f:
        head = f.read(4)
        f.seek(max(size - 32, 0))
        tail = f.read(32)
    if head != b"RRF2" or size < 36 or tail[20:28] != b"RRF2FOOT":
        raise ValueError("no RRD footer: the recording is truncated")
    offset, length = struct.unpack("<QQ", tail[:16])
    if offset + length + 32 != size:
        raise ValueError("its RRD footer does not match its size: the recording is truncated")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            stores = rr.chunk.RrdReader(tmp).recordings()
    except (Warning, RuntimeError) as err:
        raise ValueError(f"the Rerun reader refuses it: {err}") from err
    if not stores:
        raise ValueError("the Rerun reader finds no recording in it")


@contextlib.contextmanager
def open_recording(path: str | os.PathLike[str], result: Any, has_reference: bool,
                   recording_id: str | None = None) -> Iterator[Any]:
    """A Rerun recording of ``result`` written by the SDK to a temporary sibling of ``path``
    (with its default blueprint, name and run summary), then flushed, closed and checked
    (:func:`verify_rrd`) and only then moved into place
    (:func:`impactcli.files.finish_output`). On any error — the SDK's own when the disk is
    full, a sink that does not finish within :data:`SINK_TIMEOUT_S` — the temporary file is
    removed, ``path`` is untouched, and a write failure is an OutputError naming ``path``."""
    rr = import_rerun()
    log = result.log
    target = Path(path)
    prepare_output(target)
    rec = rr.RecordingStream(look.APPLICATION_ID, recording_id=recording_id)

    def finish() -> None:
        rec.flush(timeout_sec=SINK_TIMEOUT_S)
        rec.disconnect()

    open_sink = True
    tmp: Path | None = None
    try:
        with whole():  # a stop signal cannot fall between the file and its removal below
            tmp = part_path(target)
        try:
            sink_call(lambda: rec.save(str(tmp), default_blueprint=look.default_blueprint(
                log.joint_names, has_reference, duration_s=log.duration_s)), target, "open")
            rec.send_recording_name(Path(log.source.path).name or "impactcli run")
            rec.log("/run/info", rr.TextDocument(look.markdown_summary(result),
                                                 media_type="text/markdown"),
                    static=True, strict=True)
            yield rec
            open_sink = False
            sink_call(finish, target, "finish")
        except Exception as err:
            if (out := sdk_write_error(target, err)) is not None:
                raise out from err
            raise
        finish_output(tmp, target, verify_rrd)
    except BaseException:
        if open_sink:
            with contextlib.suppress(Exception):
                sink_call(rec.disconnect, target, "close", timeout_s=5.0)
        if tmp is not None:
            discard(tmp)
        raise


def _write_samples(rec: Any, result: Any, spill: ColumnFiles, n: int, has_reference: bool,
                   windows: list[tuple[int, int]], fired: dict[Any, int], max_points: int,
                   at_times: Callable[[np.ndarray], list[Any]]) -> None:
    """The plots, the markers and the lanes, one row group at a time."""
    import rerun as rr

    joints = tuple(result.log.joint_names)
    plots = {k: list(v) for k, v in PLOTS.items()}
    if has_reference:
        plots["position"].insert(0, ("reference", "position_ref"))
    streams: dict[tuple[str, str], EnvelopeStream] = {}
    marks: dict[tuple[str, str], EnvelopeStream] = {}
    last: dict[tuple[str, str], bool | None] = {}
    v_l = {j: result.thresholds.get(j, {}).get("vL") for j in joints}
    for j in joints:
        root = look.joint_entity(j)
        for plot, series in plots.items():
            names = [s for s, _ in series] + (["vL"] if plot == "loading" and v_l[j] is not None
                                              else [])
            look.style_series(rec, f"{root}/{plot}", names)
            streams[(j, plot)] = EnvelopeStream(n, len(names), max_points)
        for det in DETECTORS:
            look.style_lane(rec, j, det)
            last[(j, det)] = None
            if fired[(j, det)]:
                look.style_markers(rec, f"{root}/{look.MARKED_ON[det][0]}/{det}", det)
                marks[(j, det)] = EnvelopeStream(fired[(j, det)], 1, max_points)

    def send(entity: Any, sel: np.ndarray, rows: np.ndarray, k: int | None) -> None:
        """Rows (values..., the time's bits) selected for ``entity``: k values each, or one
        (None: a series of scalars)."""
        if sel.size:
            t_sel = np.ascontiguousarray(rows[:, -1]).view(np.int64)
            rec.send_columns(entity, indexes=at_times(t_sel), columns=rr.Scalars.columns(
                scalars=rows[:, 0] if k is None else rows[:, :k]), strict=True)

    for g in spill.groups():
        t = g["t_ns"]
        m = t.shape[0]
        if m == 0:
            continue
        t_bits = t.view(np.float64)  # the time rides along bit for bit
        keep = np.zeros(m, dtype=bool)
        for a, b in windows:
            keep[np.searchsorted(t, a, "left"):np.searchsorted(t, b, "right")] = True
        for j in joints:
            root = look.joint_entity(j)
            for plot, series in plots.items():
                cols = [g[f"{j}.{key}"] for _, key in series]
                if plot == "loading" and v_l[j] is not None:
                    cols.append(np.full(m, float(v_l[j])))
                sel, rows = streams[(j, plot)].select([*cols, t_bits], len(cols), keep)
                send(f"{root}/{plot}", sel, rows, len(cols))
            lanes = look.lanes_entity(j)
            for det in DETECTORS:
                d = g[f"{j}.{det}"].astype(bool)
                prev = last[(j, det)]
                change = np.flatnonzero(d[1:] != d[:-1]) + 1
                at = change if prev is not None and prev == bool(d[0]) else \
                    np.concatenate([[0], change])
                last[(j, det)] = bool(d[-1])
                if at.size:
                    rec.send_columns(f"{lanes}/{det}", indexes=at_times(t[at]),
                                     columns=rr.StateChange.columns(
                                         state=np.where(d[at], "detected", "clear").tolist()),
                                     strict=True)
                if (j, det) not in marks:
                    continue
                plot, sig_name = look.MARKED_ON[det]
                hit = np.flatnonzero(d)
                sel, rows = marks[(j, det)].select([g[f"{j}.{sig_name}"][hit], t_bits[hit]], 1,
                                                   keep[hit])
                send(f"{root}/{plot}/{det}", sel, rows, None)


def write_warmup_lane(rec: Any, joint: str, i_w: int, n: int,
                      at_samples: Callable[[Any], list[Any]]) -> None:
    """A joint's warm-up lane: "warm-up" from the first sample, "running" from sample
    ``i_w`` (its first after the warm-up; ``n``: none)."""
    import rerun as rr

    lane = f"{look.lanes_entity(joint)}/warmup"
    rec.log(lane, rr.StateConfiguration(
        values=["warm-up", "running"], colors=[(255, 193, 7), (76, 175, 80)]),
        static=True, strict=True)
    w_idx = np.array([0] if i_w <= 0 else ([0, i_w] if i_w < n else [0]))
    w_states = ["running"] if i_w <= 0 else ["warm-up", "running"][: len(w_idx)]
    rec.send_columns(lane, indexes=at_samples(w_idx),
                     columns=rr.StateChange.columns(state=w_states), strict=True)


def write_events(rec: Any, result: Any, n: int, at_samples: Callable[[Any], list[Any]],
                 warm_index: dict[str, int]) -> None:
    """The events' text rows and each joint's warm-up end (``warm_index``: joint → its
    first sample after the warm-up, ``n`` if none)."""
    import rerun as rr

    events = result.events
    if events:
        at = np.array([min(max(e.i_start, 0), n - 1) for e in events], dtype=np.int64)
        levels = [rr.TextLogLevel.INFO if e.in_warmup else rr.TextLogLevel.WARN for e in events]
        rec.send_columns("/events", indexes=at_samples(at), columns=rr.TextLog.columns(
            text=[look.event_text(e) for e in events], level=levels), strict=True)
    at_w, texts = [], []
    for joint in result.log.joint_names:
        w_end = result.warmup_per_joint_s.get(joint, result.warmup_end_s)
        i_w = warm_index[joint]
        if i_w < n:
            at_w.append(i_w)
            texts.append(f"warm-up ends for {joint} at {w_end:.3f} s: "
                         "events starting before are not counted")
    if at_w:
        rec.send_columns("/run/log", indexes=at_samples(np.array(at_w, dtype=np.int64)),
                         columns=rr.TextLog.columns(text=texts,
                                                    level=[rr.TextLogLevel.INFO] * len(texts)),
                         strict=True)


def write_payload_changes(rec: Any, result: Any, at_times: Callable[[np.ndarray], Any]
                          ) -> None:
    """The payload changes (docs/method.md §5c): a text row at each one's onset and one at
    its classification, on ``/payload_changes``."""
    import rerun as rr

    from ..detect.payload_words import carrying_text, change_text

    changes = list(result.payload_changes or ())
    if not changes:
        return
    t0 = int(result.log.t0_ns)
    rows = sorted([(c["t_start"], f"payload change P{k}: {change_text(c)}, classified at "
                    f"{c['t_classified']:.3f} s") for k, c in
                   enumerate(changes, 1)]
                  + [(c["t_classified"], f"payload change P{k} classified: the residual now "
                      f"carries {carrying_text(c)}") for k, c in enumerate(changes, 1)])
    at = np.array([t0 + round(t * 1e9) for t, _ in rows], dtype=np.int64)
    rec.send_columns("/payload_changes", indexes=at_times(at), columns=rr.TextLog.columns(
        text=[txt for _, txt in rows], level=[rr.TextLogLevel.INFO] * len(rows)))


def write_incidents(rec: Any, result: Any, n: int,
                    at_samples: Callable[[Any], list[Any]]) -> None:
    """The incident track: text rows with fields, the spans lane, force markers."""
    import pyarrow as pa
    import rerun as rr

    incs = list(result.incidents)
    names = look.incident_names(incs)
    labels = [look.incident_label(k, inc) for k, inc in zip(names, incs, strict=True)]
    rec.log("/incidents/contact", rr.StateConfiguration(
        values=[look.NO_CONTACT, *labels], labels=["", *labels],
        colors=[look.CLEAR_COLOR] + [look.CONTACT_COLORS.get(i.contact,
                                                             look.CONTACT_COLORS["unknown"])
                                     for i in incs],
        visible=[False] + [True] * len(incs)), static=True, strict=True)
    rec.log("/incidents/force", rr.SeriesPoints(
        names=["incident force [N]"], markers=["Circle"], colors=[look.INCIDENT_FORCE_COLOR],
        marker_sizes=[6.0]), static=True, strict=True)
    if not incs:
        rec.send_columns("/incidents/contact", indexes=at_samples(np.array([0], dtype=np.int64)),
                         columns=rr.StateChange.columns(state=[look.NO_CONTACT]), strict=True)
        return
    at = np.array([min(max(i.i_start, 0), n - 1) for i in incs], dtype=np.int64)
    # one row per incident: its text-log line and its fields, in one chunk
    text = rr.TextLog.columns(
        text=[look.incident_text(k, i) for k, i in zip(names, incs, strict=True)],
        level=[rr.TextLogLevel.INFO if i.in_warmup or getattr(i, "payload_change", None)
               is not None or getattr(i, "data_defect", None) is not None
               else rr.TextLogLevel.WARN for i in incs])
    fields = rr.AnyValues.columns(
        index=pa.array(range(1, len(incs) + 1), pa.int64()),
        link=pa.array([i.link for i in incs], pa.int64()),
        force_n=pa.array([i.force_n for i in incs], pa.float64()),
        force_at_least=pa.array([bool(i.force_at_least) for i in incs], pa.bool_()),
        contact=pa.array([i.contact for i in incs], pa.string()),
        t_end_s=pa.array([float(i.t_end) for i in incs], pa.float64()),
        detectors=pa.array([", ".join(i.detectors) for i in incs], pa.string()),
        joints=pa.array([", ".join(i.joints) for i in incs], pa.string()),
        in_warmup=pa.array([bool(i.in_warmup) for i in incs], pa.bool_()),
    )
    rec.send_columns("/incidents", indexes=at_samples(at), columns=[*text, *fields], strict=True)
    # spans: the incident's label from its first sample, "no contact" after its last
    idx: list[int] = [0] if at[0] > 0 else []
    states: list[str] = [look.NO_CONTACT] if at[0] > 0 else []
    for k, (inc, lab) in enumerate(zip(incs, labels, strict=True)):
        idx.append(int(at[k]))
        states.append(lab)
        after = min(max(inc.i_end, inc.i_start), n - 1) + 1
        nxt = int(at[k + 1]) if k + 1 < len(incs) else n
        if after < nxt:
            idx.append(after)
            states.append(look.NO_CONTACT)
    rec.send_columns("/incidents/contact", indexes=at_samples(np.array(idx, dtype=np.int64)),
                     columns=rr.StateChange.columns(state=states), strict=True)
    forced = [k for k, i in enumerate(incs) if i.force_n is not None]
    if forced:
        rec.send_columns("/incidents/force", indexes=at_samples(at[forced]),
                         columns=rr.Scalars.columns(scalars=np.array(
                             [incs[k].force_n for k in forced], dtype=np.float64)),
                         strict=True)
