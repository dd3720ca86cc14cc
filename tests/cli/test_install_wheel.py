"""`pip install .` as a user does it (a wheel, not editable), then the installed command
from a directory that is not the source tree: `orbitrig init` writes a lab configuration
from the defaults the wheel carries, and `orbitrig sweep --sim` run in it uses it.

The wheel is built without build isolation (setuptools of the test environment, the `test`
extra) and installed into a fresh venv that sees the test environment's packages
(--system-site-packages), so nothing is downloaded."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile

import h5py
import pytest

from sim.scenario_files import scenario_names
from support.paths import ROOT
from support.rig_configs import patient_link

pytestmark = pytest.mark.timeout(240)


def _run(*args, cwd, env, timeout=120):
    done = subprocess.run(
        [str(a) for a in args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 0, f"{args}: exit {done.returncode}\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    return done


#: what the build reads besides the packages (pyproject.toml, setup.py's config/, MANIFEST.in's)
BUILD_INPUTS = ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "LICENSE", "config")


def _source_copy(dst):
    """The build's inputs and every top-level package of the tree, copied to ``dst``: a build in
    the tree itself reuses its build/lib, whose packages from an earlier build would hide one that
    pyproject.toml's include patterns now miss."""
    for name in BUILD_INPUTS + tuple(p.parent.name for p in ROOT.glob("*/__init__.py")):
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dst / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            dst.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dst / name)
    return dst


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv bin folder, environment without the source tree) after installing the wheel."""
    tmp = tmp_path_factory.mktemp("wheel")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "ORBITRIG_HOME")}
    env.update(COLUMNS="200", NO_COLOR="1", PIP_DISABLE_PIP_VERSION_CHECK="1")
    _run(
        sys.executable,
        "-m",
        "pip",
        "wheel",
        "-q",
        "--no-deps",
        "--no-build-isolation",
        "-w",
        tmp / "dist",
        _source_copy(tmp / "source"),
        cwd=tmp,
        env=env,
    )
    (wheel,) = (tmp / "dist").glob("orbitrig-*.whl")
    shipped = set(zipfile.ZipFile(wheel).namelist())
    # every top-level package of the tree but the benches, the leaf ones (rigerrors, rigthreads,
    # rigunits) included: a package pyproject.toml's include patterns miss is absent from the wheel
    packages = {p.parent.name for p in ROOT.glob("*/__init__.py")} - {"bench"}
    assert {"orbitrig", "sim", "rigerrors", "rigthreads", "rigunits"} <= packages
    assert {f"{name}/__init__.py" for name in packages} <= shipped, sorted(packages)
    assert not {n.split("/")[0] for n in shipped if n.endswith(".py")} - packages  # nor a package more
    assert {
        "orbitrig/data/rig.toml",
        "orbitrig/data/matrices/demo.toml",
        "orbitrig/data/designs/kcd11-demo.toml",
        "orbitrig/data/mosquitto/mosquitto.conf",
        "sim/scenarios/sim.toml",
        "sim/scenarios/sim/clean.toml",
    } <= shipped
    (licence,) = [n for n in shipped if n.endswith(".dist-info/licenses/LICENSE")]  # pyproject's license-files
    assert "MIT License" in zipfile.ZipFile(wheel).read(licence).decode()
    _run(sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", tmp / "venv", cwd=tmp, env=env)
    bin_dir = tmp / "venv" / "bin"
    _run(bin_dir / "python", "-m", "pip", "install", "-q", "--no-index", wheel, cwd=tmp, env=env)
    return bin_dir, env


def test_installed_package_is_the_wheel(installed, tmp_path):
    bin_dir, env = installed
    done = _run(
        bin_dir / "python",
        "-c",
        "import orbitrig, rigthreads, sim.scenario_files; print(orbitrig.__file__); print(rigthreads.__file__); "
        "print(sim.scenario_files.scenario_path('clean'))",
        cwd=tmp_path,
        env=env,
    )
    for line in done.stdout.split():
        assert line.startswith(str(bin_dir.parent)), done.stdout  # not the source tree
    shown = _run(bin_dir / "orbitrig", "sim", "--help", cwd=tmp_path, env=env)  # names from sim/scenarios
    assert f"NAME: {', '.join(scenario_names())} (config/sim/)" in " ".join(shown.stdout.split())


def test_init_then_sweep_sim_in_the_lab_folder(installed, tmp_path):
    bin_dir, env = installed
    _run(bin_dir / "orbitrig", "init", "lab", cwd=tmp_path, env=env)
    lab = tmp_path / "lab"
    rig = lab / "rig.toml"
    text = rig.read_text().replace('name = "double-spool rig"', 'name = "lab rig 7"')
    # a loaded test machine answers Modbus slower (0.3 s x 2 polls was lost under tools/cpu-hog with
    # four test workers): the suite's patient link
    rig.write_text(patient_link(text))
    demo = lab / "matrices" / "demo.toml"
    demo.write_text(demo.read_text().replace('name = "demo"', 'name = "lab demo"\nrevolutions = 20'))
    _run(
        bin_dir / "orbitrig",
        "sweep",
        "--sim",
        "--sim-config",
        "clean",
        "--speedup",
        "10",
        "--out",
        tmp_path / "run",
        cwd=lab,
        env=env,
    )
    with h5py.File(tmp_path / "run" / "run.h5", "r") as f:
        assert 'name = "lab rig 7"' in f.attrs["rig_config"]
        assert f.attrs["matrix_name"] == "lab demo"
        assert f.attrs["sim_scenario_name"].endswith("sim/scenarios/sim/clean.toml")
        assert f["points/0000"].attrs["complete"]


def test_environment_variable_and_shipped_defaults(installed, tmp_path):
    bin_dir, env = installed
    _run(bin_dir / "orbitrig", "init", tmp_path / "lab", cwd=tmp_path, env=env)
    rig = tmp_path / "lab" / "rig.toml"
    rig.write_text(rig.read_text().replace("max_spin_rpm = 2500.0", "max_spin_rpm = 900.0"))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shipped = _run(bin_dir / "orbitrig", "sweep", "--sim", "--dry-run", cwd=elsewhere, env=env)
    assert "demo" in shipped.stdout
    refused = subprocess.run(
        [bin_dir / "orbitrig", "sweep", "--sim", "--dry-run"],
        cwd=elsewhere,
        env={**env, "ORBITRIG_HOME": str(tmp_path / "lab")},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert refused.returncode == 2
    assert f"{tmp_path / 'lab' / 'matrices' / 'demo.toml'}" in refused.stderr
    assert "drives.max_spin_rpm = 900" in refused.stderr
