"""The plan is data: expansion, estimates, and the dry run touches no hardware."""

import math
import subprocess
import sys

import pytest

from orbitrig import config as cfg
from orbitrig.run.plan import make_plan, summarize
from orbitrig.run.steps import Acquire, SetManual, SetSpin, StopDrives

RPM = 2 * math.pi / 60


def test_demo_plan_sequence():
    rig, m = cfg.load_rig(), cfg.load_matrix()
    steps = list(make_plan(m, rig).steps)
    kinds = [type(s).__name__ for s in steps]
    assert kinds[:7] == ["SetManual", "VerifyPressures", "SetSpin", "Settle", "Acquire", "VerifyGeometry", "StoreBlock"]
    assert kinds[-3:] == ["Identify", "CompletePoint", "StopDrives"]
    acq = [s for s in steps if isinstance(s, Acquire)]
    assert len(acq) == 10  # 5 frequencies x 2 directions
    # forward from the highest |Omega| down, then backward from the lowest up
    orbits = [s.block.orbit / (1000 * RPM) for s in acq]
    assert orbits == pytest.approx([1.2, 0.9, 0.7, 0.5, 0.3, -0.3, -0.5, -0.7, -0.9, -1.2])
    assert sorted(s.block.tag for s in acq) == sorted(f"{k:02d}_{d}" for k in range(5) for d in ("fwd", "bwd"))
    # estimates: 50 revolutions (+1 to find the trigger) at the orbit period
    a0 = acq[0]
    assert a0.revolutions == 50
    assert a0.duration == pytest.approx(51 / (1200 / 60))
    spin = next(s for s in steps if isinstance(s, SetSpin))
    assert spin.spin == pytest.approx(1000 * RPM) and spin.orbit == pytest.approx(1200 * RPM)
    assert spin.duration == pytest.approx(1200 / 600)  # ramp 600 rpm/s
    assert all(s.duration >= 0 for s in steps)


def test_paper_plan_size_and_manual_changes():
    rig, m = cfg.load_rig(), cfg.load_matrix(cfg.default_matrix_path("paper"))
    steps = list(make_plan(m, rig).steps)
    sm = summarize(steps)
    assert sm.points == 108 and sm.blocks == 2160
    manual = [s for s in steps if isinstance(s, SetManual)]
    assert len(manual) == 108
    assert sum(s.changed for s in manual) == 54  # spin is the innermost loop
    assert isinstance(steps[-1], StopDrives)
    assert sm.duration == pytest.approx(sum(s.duration for s in steps))


def test_dry_run_lists_steps_and_touches_no_hardware():
    code = (
        "import sys\n"
        "from typer.testing import CliRunner\n"
        "from orbitrig.cli import app\n"
        "r = CliRunner().invoke(app, ['sweep', '--sim', '--dry-run', '--steps'])\n"
        "print(r.output)\n"
        # the A/D board's scan-mode words (daq.adc_mode, an Enum the rig configuration validates) are no I/O
        # the simulator scenario's file found and parsed (a bad --sim-config refused): sim.config and
        # sim.scenario_files, no process
        # the drives' register map, their errors and their link's URL parser (the bounds [transports] and
        # [drives] are validated against) are no I/O either: no pymodbus, no link
        "words = {'daq', 'daq.adc_mode', 'sim', 'sim.config', 'sim.scenario_files', 'drives', 'drives.errors', 'drives.link_url',"
        " 'drives.registers'}\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('sim', 'daq', 'drives', 'can', 'pymodbus', 'h5py')\n"
        "       and m not in words]\n"
        "print('LOADED', bad)\n"
        "sys.exit(r.exit_code)\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    out = p.stdout
    assert "LOADED []" in out
    assert "acquire 50 revolutions at 20.000 Hz [04_fwd]" in " ".join(out.split())  # folded at 80 columns
    assert "matrix demo: 1 operating point, 10 orbit blocks, 46 steps" in out
    lines = [l for l in out.splitlines() if "point 0000" in l]
    assert len(lines) == 45
