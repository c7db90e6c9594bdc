"""Many logs: one executor seam (serial, local processes, Dask), URLs and globs, per-log
failures recorded in the batch summary, dead workers survived, the same timelines whatever
the executor.

One Dask LocalCluster (2 worker processes, 1 thread each) serves the whole module; logs are
short simulated ones (5 s, 250 Hz) and the model is identified once, so that the tests
measure the batch machinery, not identification.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import Result

from impactcli.errors import ImpactError
from impactcli.run.executors import (
    DaskMissingError,
    ExecutorChoice,
    TaskFailure,
    choose_executor,
    make_executor,
    run_tasks,
)
from impactcli.schema import validate

from .cli_run import invoke

distributed = pytest.importorskip("distributed")  # CI installs the dask extra

N_LOGS = 4
DURATION_S = 5.0


def _msg(res: Result) -> str:
    return f"exit {res.exit_code}\nstdout:\n{res.stdout}\nstderr:\n{res.stderr}"


@pytest.fixture(scope="module")
def cluster() -> Iterator[Any]:
    """A LocalCluster of 2 single-threaded worker processes, and a client to it."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=50) as lc, \
            distributed.Client(lc) as client:
        yield client


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """N_LOGS simulated logs (one with impacts), a corrupt one, and a model identified once."""
    from impactcli.logs import write_log
    from impactcli.sim import scenario, simulate

    root = tmp_path_factory.mktemp("fleet")
    logs = root / "logs"
    logs.mkdir()
    names = []
    for k in range(N_LOGS):
        name = "impacts" if k == 0 else "free_triangle"
        res = simulate(scenario(name, arm="assist_like", duration_s=DURATION_S), seed=k)
        p = logs / f"run{k}.csv.gz"
        write_log(res.log, p)
        names.append(p)
    bad = root / "bad" / "corrupt.csv.gz"
    bad.parent.mkdir()
    bad.write_bytes(names[1].read_bytes()[:300])  # a gzip stream cut short
    model = root / "model.json"
    r = invoke(["identify", str(names[1]), "-o", str(model)])
    assert r.exit_code == 0, _msg(r)
    return {"root": root, "logs": names, "bad": bad, "model": model}


def _detect(fleet: dict[str, Any], out: Path, *extra: str,
            inputs: list[str] | None = None) -> Result:
    args = ["detect", *(inputs or [str(p) for p in fleet["logs"]]), "-o", str(out),
            "--model", str(fleet["model"]), *extra]
    return invoke(args)


def _timelines(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(out.glob("*.timeline.json"))}


# ------------------------------------------------------------------ choosing the executor


def test_choose_executor_follows_options_then_environment() -> None:
    env = {"DASK_SCHEDULER_ADDRESS": "tcp://10.0.0.1:8786"}
    assert choose_executor(None, None, {}).kind == "serial"
    assert choose_executor(1, None, env).kind == "serial"  # an explicit --jobs wins
    assert choose_executor(3, None, env) == ExecutorChoice("processes", 3, None, "--jobs")
    c = choose_executor(None, None, env)
    assert (c.kind, c.address, c.origin) == ("dask", "tcp://10.0.0.1:8786",
                                             "DASK_SCHEDULER_ADDRESS")
    assert choose_executor(2, "local", env) == ExecutorChoice("dask", 2, "local", "--scheduler")
    assert choose_executor(None, "sched.json", {}).address == "sched.json"
    with pytest.raises(ValueError, match="--jobs"):
        choose_executor(2, "tcp://h:8786", {})


def test_missing_dask_extra_is_one_clear_line(monkeypatch: pytest.MonkeyPatch,
                                              fleet: dict[str, Any], tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed → ImportError
    with pytest.raises(DaskMissingError, match=r"pip install 'impactcli\[dask\]'"), \
            make_executor(scheduler="local"):
        pass
    r = _detect(fleet, tmp_path / "out", "--scheduler", "local")
    assert r.exit_code == 2, _msg(r)
    assert r.stderr.strip().splitlines() == [
        "impactcli: error: a Dask scheduler needs the dask extra: pip install 'impactcli[dask]'"
    ], _msg(r)
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ same answers everywhere


def test_serial_jobs_and_cluster_give_byte_identical_timelines(
        fleet: dict[str, Any], cluster: Any, tmp_path: Path) -> None:
    outs = {}
    for name, extra in [("serial", []), ("jobs2", ["--jobs", "2"]),
                        ("dask", ["--scheduler", cluster.scheduler.address])]:
        out = tmp_path / name
        summary = tmp_path / f"{name}.summary.json"
        r = _detect(fleet, out, *extra, "--summary", str(summary))
        assert r.exit_code == 0, _msg(r)
        outs[name] = _timelines(out)
        doc = json.loads(summary.read_text())
        validate(doc, "batch_summary", ImpactError, str(summary))
        assert doc["logs"] == {"total": N_LOGS, "done": N_LOGS, "failed": 0, "not_run": 0}
        assert {Path(r["log"]).name: r["sha256"] for r in doc["results"]} == {
            p.name: _sha(p) for p in fleet["logs"]}
        assert doc["executor"]["kind"] == {"serial": "serial", "jobs2": "processes",
                                           "dask": "dask"}[name]
        assert doc["hours_analysed"] == pytest.approx(N_LOGS * DURATION_S / 3600, rel=1e-3)
        # the totals are the sums of what the timelines record
        for det, n in doc["events"].items():
            assert n == sum(json.loads(b)["summary"][det]["events"]
                            for b in outs[name].values())
    assert len(outs["serial"]) == N_LOGS
    assert outs["jobs2"] == outs["serial"]
    assert outs["dask"] == outs["serial"]
    # the impacts log has adaptive events, so the comparison is not of empty timelines
    assert json.loads(outs["serial"]["run0.timeline.json"])["summary"]["adaptive"]["events"] > 0


# ------------------------------------------------------------------ failures are per log


def test_a_corrupt_log_is_reported_while_the_others_complete(
        fleet: dict[str, Any], cluster: Any, tmp_path: Path) -> None:
    out = tmp_path / "out"
    summary = tmp_path / "s.json"
    inputs = [str(p) for p in fleet["logs"][:2]] + [str(fleet["bad"]),
                                                    str(fleet["root"] / "missing.csv")]
    r = _detect(fleet, out, "--scheduler", cluster.scheduler.address, "--summary", str(summary),
                inputs=inputs)
    assert r.exit_code == 4, _msg(r)
    assert sorted(_timelines(out)) == ["run0.timeline.json", "run1.timeline.json"]
    doc = json.loads(summary.read_text())
    validate(doc, "batch_summary", ImpactError, str(summary))
    assert doc["logs"] == {"total": 4, "done": 2, "failed": 2, "not_run": 0}
    fails = {Path(f["file"]).name: f for f in doc["failures"]}
    assert set(fails) == {"corrupt.csv.gz", "missing.csv"}
    for f in fails.values():
        assert (f["class"], f["exit_code"], f["attempts"]) == ("data", 3, 1)
        assert f["reason"].startswith(f["file"])  # the message names the file
        assert f"impactcli: error: {f['reason']}" in r.stderr
    assert "not found" in fails["missing.csv"]["reason"]
    assert "2 of 4 logs failed" in r.stderr


def _die_once(marker: str) -> int:
    """Kill this worker process the first time (marker absent), return its pid after."""
    if not os.path.exists(marker):
        Path(marker).write_text("died")
        os.kill(os.getpid(), signal.SIGKILL)
    return os.getpid()


def _always_die(_: str) -> int:
    os.kill(os.getpid(), signal.SIGKILL)
    return 0  # pragma: no cover


def _square(x: int) -> int:
    return x * x


def _call(arg: tuple[str, str]) -> int:
    fn, a = arg
    return {"die_once": _die_once, "always_die": _always_die}[fn](a)


def test_local_pool_survives_a_dead_worker(tmp_path: Path) -> None:
    items = [("die_once", str(tmp_path / "m1")), ("always_die", ""),
             ("die_once", str(tmp_path / "m2"))]
    got = dict(run_tasks(_call, items, jobs=2))
    assert set(got) == {0, 1, 2}
    assert isinstance(got[0], int) and isinstance(got[2], int)  # re-run in a fresh pool
    assert isinstance(got[1], TaskFailure) and got[1].kind == "worker-lost"
    assert (tmp_path / "m1").exists() and (tmp_path / "m2").exists()


def test_cluster_survives_a_killed_worker(cluster: Any, tmp_path: Path) -> None:
    marker = tmp_path / "marker"
    items = [("die_once", str(marker))]
    got = dict(run_tasks(_call, items, client=cluster))
    assert marker.exists()  # the first attempt did kill its worker
    assert isinstance(got[0], int) and got[0] > 0
    # the cluster still works afterwards
    assert dict(run_tasks(_square, [3, 4], client=cluster)) == {0: 9, 1: 16}


def _threads(_: int) -> tuple[int, int]:
    from impactcli.cores import cores
    from impactcli.detect.adaptive import default_threads

    return cores(), default_threads(200_000)


def test_pool_workers_share_the_cores() -> None:
    """Known truth: two pool workers each take half the cores for their own threads (the
    evaluator's axes, the floor's probes), where each took all of them (two workers on
    two cores ran four threads); the main process keeps every core."""
    from impactcli.cores import cores

    got = dict(run_tasks(_threads, [0, 1], jobs=2))
    share = max(1, (os.cpu_count() or 1) // 2)
    assert got == {0: (share, share), 1: (share, share)}
    assert cores() == (os.cpu_count() or 1)


def test_a_task_that_raises_becomes_a_failure_record() -> None:
    got = dict(run_tasks(_square, [2, "x"]))  # type: ignore[list-item]
    assert got[0] == 4
    assert isinstance(got[1], TaskFailure) and got[1].kind == "error"
    assert "TypeError" in got[1].reason and "Traceback" in got[1].traceback


# ------------------------------------------------------------------ URLs and globs


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def test_file_urls_and_globs(fleet: dict[str, Any], cluster: Any, tmp_path: Path) -> None:
    logs_dir = fleet["logs"][0].parent
    out = tmp_path / "out"
    pattern = f"file://{logs_dir}/run[12].csv.gz"
    r = _detect(fleet, out, "--scheduler", cluster.scheduler.address,
                inputs=[pattern, str(logs_dir / "run3*")])
    assert r.exit_code == 0, _msg(r)
    tls = {k: json.loads(v) for k, v in _timelines(out).items()}
    assert sorted(tls) == ["run1.timeline.json", "run2.timeline.json", "run3.timeline.json"]
    for k in (1, 2):
        inp = tls[f"run{k}.timeline.json"]["input"]
        assert inp["path"] == f"file://{logs_dir}/run{k}.csv.gz"  # the URL is the source
        assert inp["sha256"] == _sha(fleet["logs"][k])
    assert tls["run3.timeline.json"]["input"]["path"] == str(fleet["logs"][3])
    # a URL read gives the same detection as the plain path
    serial = tmp_path / "plain"
    assert _detect(fleet, serial, inputs=[str(fleet["logs"][1])]).exit_code == 0
    plain = json.loads((serial / "run1.timeline.json").read_text())
    url = tls["run1.timeline.json"]
    assert plain["events"] == url["events"] and plain["thresholds"] == url["thresholds"]


def test_remote_url_in_and_url_prefix_out(fleet: dict[str, Any], tmp_path: Path) -> None:
    """fsspec's in-memory file system stands for an object store (serial: it is per process)."""
    import fsspec

    fs = fsspec.filesystem("memory")
    src = fleet["logs"][2]
    fs.pipe("/bucket/in/run2.csv.gz", src.read_bytes())
    fs.pipe("/bucket/cfg/model.json", fleet["model"].read_bytes())
    summary = "memory://bucket/out/summary.json"
    r = invoke(["detect", "memory://bucket/in/*.csv.gz", "-o", "memory://bucket/out",
             "--model", "memory://bucket/cfg/model.json", "--summary", summary])
    try:
        assert r.exit_code == 0, _msg(r)
        names = sorted(p.rsplit("/", 1)[-1] for p in fs.ls("/bucket/out", detail=False))
        assert names == ["run2.timeline.json", "summary.json"]  # no .part left behind
        tl = json.loads(fs.cat("/bucket/out/run2.timeline.json"))
        assert tl["input"]["path"] == "memory:///bucket/in/run2.csv.gz"
        assert tl["input"]["sha256"] == _sha(src)
        local = tmp_path / "local"
        assert _detect(fleet, local, inputs=[str(src)]).exit_code == 0
        ref = json.loads((local / "run2.timeline.json").read_text())
        assert tl["events"] == ref["events"]
        doc = json.loads(fs.cat("/bucket/out/summary.json"))
        validate(doc, "batch_summary", ImpactError, summary)
        assert doc["results"][0]["outputs"] == ["memory://bucket/out/run2.timeline.json"]
        assert doc["inputs"] == {"model": {"path": "memory://bucket/cfg/model.json",
                                           "sha256": _sha(fleet["model"])}}
        assert doc["results"][0]["model_source"] == "given"
        missing = invoke(["detect", "memory://bucket/in/none.csv.gz", "-o", str(tmp_path / "o")])
        assert missing.exit_code == 3, _msg(missing)
        assert "memory://bucket/in/none.csv.gz: log file not found" in missing.stderr
    finally:
        fs.rm("/bucket", recursive=True)


def test_fleet_report_from_batch_timelines_is_the_same_on_a_cluster(
        fleet: dict[str, Any], cluster: Any, tmp_path: Path) -> None:
    out = tmp_path / "out"
    inputs = [str(p) for p in fleet["logs"][:2]]
    assert _detect(fleet, out, "--jobs", "2", inputs=inputs).exit_code == 0
    timelines = sorted(str(p) for p in out.glob("*.timeline.json"))
    docs = {}
    for name, extra in [("serial", []), ("dask", ["--scheduler", cluster.scheduler.address])]:
        r = invoke(["report", *timelines, str(fleet["bad"]), "-o", str(tmp_path / f"{name}.html"),
                 "--json", str(tmp_path / f"{name}.json"), *extra])
        assert r.exit_code == 4, _msg(r)  # the corrupt log is listed, the others reported
        docs[name] = (tmp_path / f"{name}.json").read_bytes()
    assert docs["dask"] == docs["serial"]
    doc = json.loads(docs["serial"])
    assert [s["stem"] for s in doc["summary"]] == ["run0", "run1"]  # input order
    assert [Path(f["path"]).name for f in doc["failed"]] == ["corrupt.csv.gz"]


def test_a_pool_runs_under_a_tmpdir_too_long_for_a_socket(tmp_path: Path) -> None:
    """The fork server's socket would not fit a long TMPDIR's path (AF_UNIX: 107 bytes):
    the pool still runs, and leaves nothing in TMPDIR."""
    import subprocess

    long = tmp_path / ("t" * 100)
    long.mkdir()
    code = ("import math; from impactcli.run.executors import run_tasks; "
            "print(sorted(dict(run_tasks(math.factorial, [3, 4], jobs=2)).items()))")
    r = subprocess.run([sys.executable, "-c", code], env={**os.environ, "TMPDIR": str(long)},
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[(0, 6), (1, 24)]"
    assert not list(long.iterdir())
