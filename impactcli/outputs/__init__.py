"""Outputs: a run's result and its chunks formatted into files, no maths; one writer per
output, each fed the replay's chunks (a run's ``on_chunk``).

* :mod:`.timeline` — the detection timeline JSON;
* :mod:`.signals` — the per-sample signals Parquet (and the writers' temporary spills);
* :mod:`.rerun` — the Rerun ``.rrd`` recording, :mod:`.rerun_blueprint` its look;
* :mod:`.report` — the safety-audit report (HTML and JSON);
* :mod:`.decimate` — the peak-preserving decimation of long series for display.

Nothing heavy is imported here, so ``impactcli --help`` stays fast.
"""
