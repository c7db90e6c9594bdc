"""NumPy ``.npz`` archives through a channel map (formats.md, "Channel maps").

Arrays are addressed by key; a 2-D array (N, k) by key plus column ``index``. Every array
used must have the time array's length N. Float time in ``unit`` is rounded to ns.
"""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path

import numpy as np

from ..errors import ChannelMapError, LogFormatError
from .assemble import JointChannels
from .channel_map import TIME_UNITS, ChannelMap, ChannelRef, require_time
from .csv import channels_from_columns
from .repair import DROPPABLE_SIGNALS, repair_samples


def read_npz_channels(path: Path, cmap: ChannelMap) -> JointChannels:
    """Read an ``.npz`` archive into :class:`JointChannels` following ``cmap``."""
    where = str(path)
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise LogFormatError(f"{where}: not a readable .npz archive: {err}") from err
    with archive:
        keys = list(archive.files)
        cache: dict[str, np.ndarray] = {}
        mapname = cmap.path or cmap.name

        def get(ref: ChannelRef, what: str) -> np.ndarray:
            key = str(ref.source)
            if key not in keys:
                raise ChannelMapError(
                    f"{where}: channel map {mapname}: {what} points at array {key!r}, which is "
                    f"not in the archive (keys: {', '.join(keys)})"
                )
            if key not in cache:
                try:
                    cache[key] = np.asarray(archive[key])
                except (ValueError, zipfile.BadZipFile, zlib.error, EOFError, OSError) as err:
                    # object arrays need pickle (refused); a corrupt or cut member
                    raise LogFormatError(f"{where}: array {key!r} cannot be read: {err}") from err
            a = cache[key]
            if ref.index is None:
                if a.ndim != 1:
                    raise ChannelMapError(
                        f"{where}: channel map {mapname}: {what}: array {key!r} has shape "
                        f"{a.shape}; give a column 'index'"
                    )
                return a
            if a.ndim != 2 or ref.index >= a.shape[1]:
                raise ChannelMapError(
                    f"{where}: channel map {mapname}: {what}: column {ref.index} does not exist "
                    f"in array {key!r} of shape {a.shape}"
                )
            return a[:, ref.index]

        tspec = require_time(cmap, where)
        t_raw = get(tspec.ref, "time")
        n = t_raw.shape[0]
        tkey = str(tspec.ref.source)
        cols: dict[str, np.ndarray] = {}
        labels: dict[tuple[str, int], str] = {}
        for sig, j, ref in cmap.refs():
            what = f"{cmap.joints[j]}.{sig}"
            v = get(ref, what)
            if v.shape[0] != n:
                raise LogFormatError(
                    f"{where}: mismatched channel lengths: {tkey!r} has {n} samples but "
                    f"{ref.label()!r} ({what}) has {v.shape[0]}"
                )
            if not np.issubdtype(v.dtype, np.number) or np.iscomplexobj(v):
                raise LogFormatError(
                    f"{where}: array {ref.label()!r} is not real numbers ({v.dtype})"
                )
            lab = ref.label()
            labels[(sig, j)] = lab
            cols[lab] = v.astype(np.float64)
        used = {str(r.source) for _, _, r in cmap.refs()} | {tkey}
        ignored = [k for k in keys if k not in used]
    unit_ns = TIME_UNITS[tspec.unit]
    if np.issubdtype(t_raw.dtype, np.integer):
        t_ns = t_raw.astype(np.int64) * unit_ns
    elif np.issubdtype(t_raw.dtype, np.floating):
        if not np.all(np.isfinite(t_raw)):
            i = int(np.argmax(~np.isfinite(t_raw)))
            raise LogFormatError(f"{where}: array {tkey!r}, sample {i}: time is not finite")
        t_ns = np.round(t_raw.astype(np.float64) * unit_ns).astype(np.int64)
    else:
        raise LogFormatError(f"{where}: time array {tkey!r} is not numeric ({t_raw.dtype})")
    if tspec.offset:
        t_ns = t_ns + round(tspec.offset * unit_ns)
    # the arrays' labels (``positions[:, 2]``) do not name the signal: say which may be empty
    keep_empty = {lab for (sig, _), lab in labels.items() if sig in DROPPABLE_SIGNALS}
    t_ns, cols, repairs = repair_samples(t_ns, cols, where=where, time_name=tkey,
                                         keep_empty=keep_empty)
    if tspec.start_at_zero:
        t_ns = t_ns - t_ns[0]
    return channels_from_columns(cmap, t_ns, cols, labels, ignored, repairs)
