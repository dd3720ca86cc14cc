"""The [drives] section of rig.toml: link-loss tolerance against the drives' watchdog."""

from __future__ import annotations

import warnings

import pytest

from orbitrig.config import Drives, load_rig
from orbitrig.errors import ConfigError

from support.cli_helpers import orbitrig
from support.paths import ROOT


def test_shipped_rig_declares_a_link_loss_well_before_the_watchdog():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = load_rig(ROOT / "config" / "rig.toml").drives
    assert d.link_loss_polls == 3
    assert d.link_loss_time_s == pytest.approx(3 * (0.1 + 0.15))
    assert d.link_loss_time_s <= 0.8 * d.comm_loss_timeout_s


def test_defaults_pass_without_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert Drives().link_loss_time_s < Drives().comm_loss_timeout_s


def test_link_loss_after_the_watchdog_is_refused(tmp_path):
    text = (ROOT / "config" / "rig.toml").read_text()
    bad = text.replace("timeout_s = 0.15", "timeout_s = 0.4", 1)
    assert bad != text
    path = tmp_path / "rig.toml"
    path.write_text(bad)
    with pytest.raises(ConfigError, match="link_loss_polls 3 x .* = 1.50 s is not below"):
        load_rig(path)


def test_close_margin_warns():
    with pytest.warns(UserWarning, match="close to comm_loss_timeout_s"):
        Drives(timeout_s=0.2)  # 3 x 0.3 s = 0.9 s of a 1 s watchdog


@pytest.mark.parametrize("n", [0, -2])
def test_link_loss_polls_positive(n):
    with pytest.raises(ValueError, match="link_loss_polls"):
        Drives(link_loss_polls=n)


def test_close_margin_warning_names_the_file_and_line_of_the_setting(tmp_path):
    text = (ROOT / "config" / "rig.toml").read_text()
    close = text.replace("timeout_s = 0.15", "timeout_s = 0.2", 1)
    path = tmp_path / "rig.toml"
    path.write_text(close)
    line = next(n for n, s in enumerate(close.splitlines(), 1) if s.startswith("link_loss_polls"))
    with pytest.warns(UserWarning, match=r"link_loss_polls 3 x .* = 0.90 s is close to") as caught:
        load_rig(path)
    (w,) = [w for w in caught if "comm_loss_timeout_s" in str(w.message)]
    assert (w.filename, w.lineno) == (str(path), line)  # the operator's file, not pydantic's


def test_a_close_margin_is_shown_at_the_rig_toml_line_on_the_terminal(tmp_path):
    text = (ROOT / "config" / "rig.toml").read_text()
    path = tmp_path / "rig.toml"
    path.write_text(text.replace("timeout_s = 0.15", "timeout_s = 0.2", 1))
    done = orbitrig("sweep", "--sim", "--dry-run", "--config", str(path))
    assert done.returncode == 0, done.stderr
    first = done.stderr.splitlines()[0]
    assert first.startswith(f"{path}:") and "close to comm_loss_timeout_s" in first, done.stderr
    assert "pydantic" not in done.stderr
