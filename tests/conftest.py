"""Shared fixtures: small logs built in code, the real-log folder (skipped when absent:
:data:`REAL_LOGS`); with pytest-xdist, the numba kernels compiled once before the workers
start (tests/jit_warmup.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from impactcli.types import LogSource, RobotLog

REPO = Path(__file__).resolve().parents[1]
#: The public real recordings (a UR arm's ``ur_ext_observer/``, a KUKA LWR4's
#: ``kuka_lwr4/``), which the repository does not ship: ``IMPACTCLI_REAL_LOGS``, else
#: ``shared/real_logs`` beside the repository (the developers' machines).
REAL_LOGS = Path(os.environ.get("IMPACTCLI_REAL_LOGS", REPO.parent / "shared" / "real_logs"))
REAL_LOGS_ABSENT = ("the real robot recordings (UR, KUKA LWR4) are not on this machine: set "
                    "IMPACTCLI_REAL_LOGS to their folder to run this test")


@pytest.hookimpl(trylast=True)  # after the terminal reporter is there
def pytest_configure(config: pytest.Config) -> None:
    """In pytest-xdist's controlling process (``-n N``), before its workers start: the
    numba kernels compiled into numba's cache by two processes side by side, so that the
    workers load them instead of each compiling them again (tests/jit_warmup.py). A
    warm-up that fails changes nothing: the tests compile what they need."""
    if (hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None)
            or config.option.collectonly):
        return
    from .jit_warmup import PARTS

    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line("compiling the numba kernels once for the workers "
                            "(tests/jit_warmup.py; under a second when numba's cache has them)")
    procs = [subprocess.Popen([sys.executable, "-m", "tests.jit_warmup", part], cwd=REPO,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
             for part in PARTS]
    for p in procs:
        try:
            p.wait(timeout=600)
        except subprocess.TimeoutExpired:  # pragma: no cover - a machine far slower
            p.kill()
            p.wait()


@pytest.fixture
def real_logs() -> Path:
    """The folder of real robot logs (:data:`REAL_LOGS`); skips the test when absent."""
    if not REAL_LOGS.is_dir():
        pytest.skip(REAL_LOGS_ABSENT)
    return REAL_LOGS


def read_kuka(real_logs: Path) -> RobotLog:
    """The real KUKA LWR4 log through its shipped map; its one warning asserted: over its
    last 0.11 s its positions stop while its velocities go on (logs/velocity_check.py)."""
    from impactcli.errors import ImpactWarning
    from impactcli.logs import read_log

    with pytest.warns(ImpactWarning, match="tell two motions at 25.014 s to the log's end"):
        return read_log(real_logs / "kuka_lwr4" / "measurements_1.npz",
                        channel_map="kuka_lwr4")


def make_log(n: int = 500, joints: tuple[str, ...] = ("j1", "j2"), dt: float = 0.004,
             with_ref: bool = True, seed: int = 0) -> RobotLog:
    """A small smooth log with references, for tests that need any valid RobotLog."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    J = len(joints)
    w = 2 * np.pi * (0.5 + np.arange(J) * 0.3)
    q_ref = 0.5 * np.sin(np.outer(t, w))
    qd_ref = 0.5 * w * np.cos(np.outer(t, w))
    qdd_ref = -0.5 * w**2 * np.sin(np.outer(t, w))
    q = q_ref + 1e-3 * rng.standard_normal((n, J))
    tau = 2.0 * qdd_ref + 0.3 * np.sign(qd_ref) + 0.05 * rng.standard_normal((n, J))
    return RobotLog(
        t_ns=np.round(t * 1e9).astype(np.int64), joint_names=joints, position=q, torque=tau,
        position_ref=q_ref if with_ref else None, velocity_ref=qd_ref if with_ref else None,
        acceleration_ref=qdd_ref if with_ref else None,
        source=LogSource("<test>", "0" * 64, "memory"),
    )


@pytest.fixture
def small_log() -> RobotLog:
    """A 2-joint, 2-second, 250 Hz log with references."""
    return make_log()
