"""Outputs: formatting a :class:`~impactcli.result.DetectionResult` into files, no maths.

* :mod:`.timeline` — the detection timeline JSON;
* :mod:`.signals` — the per-sample signals Parquet;
* :mod:`.rerun` — the Rerun ``.rrd`` recording (rerun-sdk imported lazily inside it);
* :mod:`.decimate` — the peak-preserving decimation of long series for display.

Nothing heavy is imported here, so ``impactcli --help`` stays fast.
"""
