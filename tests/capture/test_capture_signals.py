"""psbench-capture stopped by SIGINT, SIGTERM or SIGHUP: LEDs off (the controller's
STATE? reads zeros), the partial folder removed, one line; a SIGKILLed capture's
partial folder is removed (and named) by the next capture."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

_BIN = Path(sys.executable).parent / "psbench-capture"


def _start(tmp_path, out="cap"):
    """A capture frozen (SIGSTOP) mid-capture, once its first LED frame is written: a
    signal sent now lands mid-capture however loaded the machine is (a capture left
    running could reach its last frame before the signal arrives), so a small capture
    will do."""
    # timeout=20: the simulated controller answers from a thread of the capture itself,
    # which a loaded machine (parallel tests) can delay past the default 1 s reply timeout
    proc = subprocess.Popen([str(_BIN), "rig=sim", "size=256", f"out={out}", "progress=false",
                             "timeout=20"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    t0 = time.time()
    while time.time() - t0 < 600 and not list(tmp_path.glob(f".{out}.partial-*/001.png")):
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    proc.send_signal(signal.SIGSTOP)
    assert list(tmp_path.glob(f".{out}.partial-*/001.png")), "the capture never wrote a frame"
    assert proc.poll() is None and not (tmp_path / out).exists(), "the capture ended already"
    return proc


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_signal_turns_the_leds_off_and_removes_the_partial_folder(tmp_path, sig):
    proc = _start(tmp_path)
    proc.send_signal(getattr(signal, sig))
    proc.send_signal(signal.SIGCONT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines == [f"psbench-capture: interrupted ({sig}); LEDs off (STATE? 0 0 0 0 0 0 0 0); "
                     "partial output folder removed"], err
    assert "Traceback" not in err
    assert sorted(os.listdir(tmp_path)) == []         # no output, no partial folder


def test_next_capture_removes_a_killed_captures_partial_folder(tmp_path):
    proc = _start(tmp_path)
    proc.kill()
    proc.wait(timeout=30)
    left = list(tmp_path.glob(".cap.partial-*"))
    assert len(left) == 1
    p = subprocess.run([str(_BIN), "rig=sim", "size=16", "out=small", "progress=false",
                        "targets=none"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    assert str(left[0]) in p.stderr and "partial folder" in p.stderr
    assert sorted(os.listdir(tmp_path)) == ["small"]
    assert (tmp_path / "small").stat().st_mode & 0o777 == 0o777 & ~_umask()


def _umask():
    old = os.umask(0)
    os.umask(old)
    return old
