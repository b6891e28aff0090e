"""Rig capture over a real pseudo-terminal: protocol, faults, atomic folders, full pipeline."""
from __future__ import annotations

import numpy as np
import pytest

serial = pytest.importorskip("serial")

from psbench.capture import (DeviceTimeout, Disconnected, LedController, PortBusy,  # noqa: E402
                             PortNotFound, ProtocolError, capture, capture_all)
from psbench.capture.camera import FolderCamera  # noqa: E402
from psbench.capture.cli import main as capture_main  # noqa: E402
from psbench.capture.protocol import parse_command, parse_reply  # noqa: E402
from psbench.capture.sim import RigConfig, SimCamera, SimController, SimRig  # noqa: E402

SIZE = 96
LIGHTS = "30x4+60x4"


@pytest.fixture(scope="module")
def rig():
    return SimRig(RigConfig(size=SIZE, lights=LIGHTS, surface="penny"))


def _ne(n, truth, mask):
    return float(np.degrees(np.arccos(np.clip((n * truth).sum(-1), -1, 1)))[mask].mean())


def _leftovers(tmp_path):
    return sorted(p.name for p in tmp_path.iterdir())


# --------------------------------------------------------------------------- protocol
def test_protocol_parsing():
    assert parse_command("LED 3 350") == ("LED", (3, 350))
    assert parse_command("id?") == ("ID?", ())
    with pytest.raises(KeyError):
        parse_command("FOO")
    with pytest.raises(ValueError):
        parse_command("LED 1")
    assert parse_reply("PSLED 16 1.2", "ID") == (16, "1.2")
    assert parse_reply("OK", "OK") is None
    assert parse_reply("ERR 3 LED index out of range", "OK") == ("ERR", 3, "LED index out of range")
    assert parse_reply("STATE 0 350 0", "STATE") == [0, 350, 0]


def test_driver_talks_to_sim_over_pty():
    with SimController(4, firmware="t1") as dev, LedController(dev.port, timeout=2.0) as ctl:
        assert dev.port.startswith("/dev/")
        assert ctl.identify() == (4, "t1")
        ctl.led(2, 350)
        assert dev.leds.tolist() == [0, 0, 350, 0]
        assert ctl.state() == [0, 0, 350, 0]
        assert ctl.max_current() == 1000
        with pytest.raises(ProtocolError, match="ERR 4"):
            ctl.command("LED 1 5000")
        with pytest.raises(ProtocolError, match="ERR 1"):
            ctl.command("BLINK")
        ctl.off()
        assert dev.all_off
        assert dev.log[:2] == ["ID?", "LED 2 350"]


def test_absent_port():
    with pytest.raises(PortNotFound, match="/dev/psbench-no-such-port.*does not exist"):
        LedController("/dev/psbench-no-such-port")


def test_busy_port():
    with SimController(2) as dev, LedController(dev.port, timeout=0.3):
        with pytest.raises(PortBusy, match="busy"):
            LedController(dev.port, timeout=0.3)


def test_silent_device_times_out():
    with SimController(2, fault="silence") as dev, LedController(dev.port, timeout=0.2) as ctl:
        with pytest.raises(DeviceTimeout, match=r"did not answer 'ID\?' within 0.2 s"):
            ctl.identify()


# --------------------------------------------------------------------------- faults in a capture
@pytest.mark.parametrize("fault, after, exc", [
    ("silence", 6, DeviceTimeout),      # device stops answering mid-capture
    ("garbage", 6, ProtocolError),      # replies turn to garbage
    ("disconnect", 6, Disconnected),    # cable pulled mid-capture
    ("error", 6, ProtocolError),        # firmware reports a fault
])
def test_fault_mid_capture_leaves_leds_off_and_no_folder(rig, tmp_path, fault, after, exc):
    out = tmp_path / "cap"
    with SimController(rig.k, fault=fault, after=after) as dev:
        with LedController(dev.port, timeout=0.3) as ctl:
            with pytest.raises(exc):
                capture(ctl, SimCamera(rig, dev), out, rig.nominal, progress=False)
        # the device's own record: an LED was on when the fault hit, all are off now
        assert any(c.startswith("LED") and not c.endswith(" 0") for c in dev.log)
        assert dev.all_off, dev.leds
        if fault != "disconnect":
            assert dev.log[-1] == "OFF"  # the finally block switched them off
    assert not out.exists()
    assert _leftovers(tmp_path) == []  # no folder, no temp dir


def test_ctrl_c_from_camera_callback(rig, tmp_path):
    def boom(i):
        if i == 4:
            raise KeyboardInterrupt

    out = tmp_path / "cap"
    with SimController(rig.k) as dev, LedController(dev.port, timeout=2.0) as ctl:
        with pytest.raises(KeyboardInterrupt):
            capture(ctl, SimCamera(rig, dev, callback=boom), out, rig.nominal, progress=False)
        assert dev.all_off and dev.log[-1] == "OFF"
        assert any(c.startswith("LED") and not c.endswith(" 0") for c in dev.log)
    assert _leftovers(tmp_path) == []


def test_progress_line_on_stderr(rig, tmp_path, capsys):
    with SimController(rig.k) as dev, LedController(dev.port, timeout=2.0) as ctl:
        capture(ctl, SimCamera(rig, dev), tmp_path / "cap", rig.nominal, progress=True)
        assert dev.all_off
    err = capsys.readouterr().err
    assert "capture: 9/9 LED 7" in err and "capture: done" in err


def test_capture_folder_reads_back(rig, tmp_path):
    from psbench.io import read_dataset
    with SimController(rig.k) as dev, LedController(dev.port, timeout=2.0) as ctl:
        capture(ctl, SimCamera(rig, dev), tmp_path / "cap", rig.nominal, progress=False,
                object_mask=rig.surface.object_mask, normals=rig.surface.normals)
    ds = read_dataset(tmp_path / "cap")
    assert ds.images.shape == (8, SIZE, SIZE) and ds.meta["bits"] == 8 and ds.meta["raw"]
    assert ds.lights.n_rings == 2 and not ds.meta["calibrated"]
    assert (tmp_path / "cap" / "dark.png").is_file()
    # a folder camera replays the frames
    cam = FolderCamera(tmp_path / "cap", "0*.png")
    assert cam.grab().shape == (SIZE, SIZE)


def test_cli_bad_args_and_sim_capture(tmp_path, capsys):
    assert capture_main(["rig=nope", f"out={tmp_path / 'x'}"]) == 2
    assert capture_main(["out"]) == 2
    assert capture_main(["rig=serial", "port=/dev/psbench-none", f"out={tmp_path / 'x'}",
                         "camera=" + str(tmp_path)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert capture_main(["rig=sim", f"out={tmp_path / 'c'}", "size=48", "targets=none",
                         "progress=false", "lights=45x4"]) == 0
    assert (tmp_path / "c" / "psbench.json").is_file()


# --------------------------------------------------------------------------- acceptance
@pytest.mark.filterwarnings("ignore:response fit")
def test_capture_calibrate_solve_matches_ideal(rig, tmp_path):
    """psbench-capture rig=sim -> psbench-calibrate all -> read_dataset -> solve:
    NE within 1 deg of solving the simulator's ideal images of the same scene."""
    from psbench.calibrate import main as calibrate_main
    from psbench.io import read_dataset
    from psbench.solve import solve

    out = tmp_path / "cap"
    with SimController(rig.k) as dev, LedController(dev.port, timeout=2.0) as ctl:
        capture_all(rig, ctl, out, device=dev, progress=False)
        assert dev.all_off
    assert calibrate_main(["all", str(out)]) == 0
    ds = read_dataset(out)                      # calibration applied automatically
    assert ds.meta["calibrated"]
    assert set(ds.meta["calibration_steps"]) >= {"dark", "response", "directions", "nearlight",
                                                 "flat", "powers", "pixelsize"}
    raw = read_dataset(out, calibration="none")
    ideal = rig.ideal()
    ne = {}
    for name, imgs, lights in (("cal", ds.images, ds.lights), ("raw", raw.images, raw.lights),
                               ("ideal", ideal.images, ideal.lights)):
        res = solve(imgs, lights, mask="None", object_mask=ds.object_mask)
        ne[name] = _ne(res.normals, ds.normals, ds.object_mask)
    print("NE (deg):", {k: round(v, 3) for k, v in ne.items()})
    assert abs(ne["cal"] - ne["ideal"]) < 1.0, ne
    assert ne["raw"] > ne["ideal"] + 2.0, ne  # the imperfections matter


@pytest.mark.filterwarnings("ignore:response fit")
def test_harness_runs_on_calibrated_capture(rig, tmp_path):
    """`psbench data=<capture folder>` path: the harness reads the folder through io."""
    run = pytest.importorskip("psbench.harness.run")
    from psbench.calibrate import calibrate_folder

    out = tmp_path / "cap"
    with SimController(rig.k) as dev, LedController(dev.port, timeout=2.0) as ctl:
        capture_all(rig, ctl, out, device=dev, progress=False)
    calibrate_folder(out)
    p = run.normalize({"data": str(out), "mask": "None", "lights": None})
    row = run.execute(p)
    assert row["status"] == "ok", row.get("error")
    ideal = rig.ideal()
    from psbench.solve import solve
    ne_ideal = _ne(solve(ideal.images, ideal.lights, mask="None").normals, rig.surface.normals,
                   rig.surface.object_mask)
    assert abs(row["ne_mean"] - ne_ideal) < 1.0


def test_cli_ctrl_c_exit_code(tmp_path, monkeypatch, capsys):
    import psbench.capture.sim as sim
    orig = sim.SimCamera.grab

    def grab(self):
        if self.count == 3:
            raise KeyboardInterrupt
        return orig(self)

    monkeypatch.setattr(sim.SimCamera, "grab", grab)
    rc = capture_main(["rig=sim", f"out={tmp_path / 'c'}", "size=32", "targets=none",
                       "progress=false"])
    assert rc == 130
    assert "interrupted" in capsys.readouterr().err
    assert _leftovers(tmp_path) == []
