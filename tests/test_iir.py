"""impactcli.model.iir: SciPy's filter design and recursive filtering without importing
scipy.signal, the same bits (its module docstring)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from impactcli.model import iir


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_butter_lowpass_is_scipys(order: int) -> None:
    rng = np.random.default_rng(order)
    for wn in [1e-4, 0.002, 0.02, 0.1, 0.25, 0.5, 0.8, 0.999, *rng.uniform(0, 1, 40)]:
        b, a = iir.butter_lowpass(order, wn)
        sb, sa = signal.butter(order, wn)
        assert b.dtype == sb.dtype and a.dtype == sa.dtype
        assert np.array_equal(b, sb) and np.array_equal(a, sa), wn


def test_butter_lowpass_refuses_what_scipy_refuses() -> None:
    for wn in (0.0, 1.0, -0.1, 1.5):
        with pytest.raises(ValueError):
            iir.butter_lowpass(2, wn)
    with pytest.raises(ValueError):
        iir.butter_lowpass(0, 0.1)


def test_bilinear_is_scipys() -> None:
    """The state-variable filter's designs (impactcli.model.derivatives) at many rates
    and cut-offs, and random analog filters."""
    rng = np.random.default_rng(7)
    cases = []
    for fs in (100.0, 125.0, 250.0, 500.0, 1000.0, 1000.0001, 4000.0):
        for wc in (0.5, 5.0, 20.0, 0.39 * fs):
            w = 2.0 * fs * np.tan(np.pi * wc / fs)
            den = np.array([1.0, np.sqrt(2.0) * w, w * w])
            for num in ([0.0, 0.0, w * w], [0.0, w * w, 0.0], [w * w, 0.0, 0.0]):
                cases.append((np.array(num), den, fs))
    for _ in range(50):
        den = rng.normal(size=3) + np.array([3.0, 0.0, 0.0])
        cases.append((rng.normal(size=rng.integers(1, 4)), den, float(rng.uniform(10, 2000))))
    for num, den, fs in cases:
        b, a = iir.bilinear(num, den, fs)
        sb, sa = signal.bilinear(num, den, fs=fs)
        assert np.array_equal(b, sb) and np.array_equal(a, sa), (num, den, fs)


def test_lfilter_zi_is_scipys() -> None:
    rng = np.random.default_rng(3)
    designs = [signal.butter(k, w) for k in (1, 2, 3) for w in (0.01, 0.2, 0.7)]
    designs += [(np.array([1 - 0.9]), np.array([1.0, -0.9])),
                (rng.normal(size=2), np.array([2.0, -0.5, 0.1]))]
    for b, a in designs:
        assert np.array_equal(iir.lfilter_zi(b, a), signal.lfilter_zi(b, a))


@pytest.mark.parametrize("shape", [(1,), (7,), (1000,), (500, 3), (64, 2, 2)])
def test_lfilter_is_scipys(shape: tuple[int, ...]) -> None:
    """Bit for bit, continued over consecutive chunks, for the replay's filters (2nd-order
    Butterworths, the SVF designs, first-order poles) and b and a of unequal lengths: the
    kernels of orders 1-3 and the general one (a 4th-order Butterworth)."""
    rng = np.random.default_rng(sum(shape))
    x = rng.normal(size=shape) * 10.0 ** rng.integers(-6, 6)
    w = 2.0 * 1000.0 * np.tan(np.pi * 20.0 / 1000.0)
    designs = [signal.butter(2, 0.004), signal.butter(2, 0.6), signal.butter(3, 0.1),
               signal.butter(4, 0.2),
               signal.bilinear([0.0, w * w, 0.0], [1.0, np.sqrt(2.0) * w, w * w], fs=1000.0),
               (np.array([0.05]), np.array([1.0, -0.95])),
               (np.array([0.5, 0.2, 0.1, 0.05]), np.array([2.0, -0.3])),
               (np.array([1.0]), np.array([3.0, 0.1, -0.2, 0.05]))]
    for b, a in designs:
        order = max(len(a), len(b)) - 1
        zi = rng.normal(size=(order, *shape[1:]))
        y, zf = iir.lfilter(b, a, x, zi)
        sy, szf = signal.lfilter(b, a, x, axis=0, zi=zi)
        assert np.array_equal(y, sy) and np.array_equal(zf, szf)
        cut = shape[0] // 3
        y1, z1 = iir.lfilter(b, a, x[:cut], zi)
        y2, z2 = iir.lfilter(b, a, x[cut:], z1)
        assert np.array_equal(np.concatenate([y1, y2]), sy) and np.array_equal(z2, szf)


def test_lfilter_refuses_fir_and_bad_zi() -> None:
    with pytest.raises(ValueError, match="recursive"):
        iir.lfilter([1.0, 0.5], [1.0], np.ones(4), np.zeros(1))
    with pytest.raises(ValueError, match="zi"):
        iir.lfilter([1.0], [1.0, -0.5], np.ones((4, 2)), np.zeros((1, 3)))


def test_replay_does_not_import_scipy_signal() -> None:
    """The point of the module: a replay with a model and thresholds known needs no
    scipy.signal (checked in a fresh interpreter)."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    code = (
        "import sys, warnings; warnings.simplefilter('ignore')\n"
        "from impactcli.config import load_config\n"
        "from impactcli.logs import read_log\n"
        "from impactcli.run.collect import detect_in_memory\n"
        f"cfg = load_config({str(root / 'sample_logs' / 'heavy_geared.config.toml')!r})\n"
        f"log = read_log({str(root / 'sample_logs' / 'csv' / 'heavy_impacts.csv.gz')!r})\n"
        "detect_in_memory(log.slice(0, 3000), config=cfg)\n"
        "print('scipy.signal' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=root, check=True)
    assert out.stdout.strip() == "False", out.stderr[-2000:]
