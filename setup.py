"""Build hook: the wheel carries the default configuration.

config/ of the source tree stays the one copy. When a wheel is built, its files are
copied into the package: rig.toml, matrices/, designs/, mosquitto/ and calibration/ as orbitrig/data
(orbitrig.config.home.shipped_config), the simulator's scenarios sim.toml and sim/ as
sim/scenarios (sim.scenario_files.SCENARIO_DIR). An editable install reads config/ in place.
Everything else is in pyproject.toml.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

CONFIG = Path(__file__).resolve().parent / "config"
SHIPPED = {
    "orbitrig/data": ("rig.toml", "matrices", "designs", "mosquitto", "calibration"),
    "sim/scenarios": ("sim.toml", "sim"),
}


class BuildWithConfig(build_py):
    """build_py, then config/'s defaults copied into the built packages."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        for target, names in SHIPPED.items():
            for name in names:
                src, dst = CONFIG / name, Path(self.build_lib) / target / name
                if src.is_dir():
                    shutil.copytree(src, dst, dirs_exist_ok=True)
                else:
                    dst.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(src, dst)


setup(cmdclass={"build_py": BuildWithConfig})
