"""Where the configuration comes from (orbitrig.config.home) and `orbitrig init DIR`:
--config, then $ORBITRIG_HOME, then the current directory, then the shipped defaults;
the lab's matrices and designs before the shipped ones; the broker configuration that
init writes runs a real mosquitto."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from orbitrig import config as cfg
from orbitrig.config.lab import write_lab
from orbitrig.errors import ConfigError
from support.cli_helpers import orbitrig
from support.mqtt_helpers import AS_ROOT, ACCOUNTS, end_process, launch_mosquitto, on_free_ports, private_copy

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def lab(tmp_path, monkeypatch):
    """A lab folder written by init, the environment and current directory neutral."""
    monkeypatch.delenv(cfg.HOME_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "lab"
    write_lab(folder)
    (folder / "rig.toml").write_text(
        (folder / "rig.toml").read_text().replace('name = "double-spool rig"', 'name = "lab rig"')
    )
    return folder


def test_shipped_defaults_are_the_source_trees_config(tmp_path, monkeypatch):
    monkeypatch.delenv(cfg.HOME_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    assert cfg.shipped_config() == REPO / "config"
    assert cfg.default_rig_path() == REPO / "config" / "rig.toml"
    assert cfg.load_rig().name == "double-spool rig"


def test_lookup_order_config_then_env_then_cwd(lab, tmp_path, monkeypatch):
    other = tmp_path / "other"
    write_lab(other)
    assert cfg.load_rig().name == "double-spool rig"  # tmp_path holds no rig.toml: shipped
    monkeypatch.chdir(lab)
    assert cfg.load_rig().name == "lab rig"  # the current directory
    monkeypatch.setenv(cfg.HOME_ENV, str(other))
    assert cfg.default_rig_path() == other / "rig.toml"  # the environment before the current directory
    assert cfg.config_home(lab / "rig.toml") == lab  # --config before everything


def test_matrix_names_from_the_lab_first(lab, monkeypatch):
    (lab / "matrices" / "demo.toml").write_text(
        (lab / "matrices" / "demo.toml").read_text().replace('name = "demo"', 'name = "lab demo"')
    )
    (lab / "matrices" / "mine.toml").write_text((lab / "matrices" / "demo.toml").read_text())
    (lab / "matrices" / "paper.toml").unlink()  # then the shipped one
    assert cfg.load_matrix(cfg.matrix_file("demo", rig_path=lab / "rig.toml")).name == "lab demo"
    assert cfg.load_matrix(cfg.matrix_file("paper", rig_path=lab / "rig.toml")).file.startswith(str(REPO))
    monkeypatch.setenv(cfg.HOME_ENV, str(lab))
    assert cfg.load_matrix(cfg.default_matrix_path()).name == "lab demo"
    with pytest.raises(ConfigError, match=r"available: demo, designed, eccentricity, mine, paper"):
        cfg.matrix_file("nothing")


def test_a_design_beside_the_matrix_folder_wins(lab):
    design = (lab / "designs" / "kcd11-demo.toml").read_text()
    (lab / "designs" / "kcd11-demo.toml").write_text(design.replace("ratios = [0.65,", "ratios = [0.25,"))
    mat = cfg.load_matrix(lab / "matrices" / "designed.toml")
    shipped = cfg.load_matrix(REPO / "config" / "matrices" / "designed.toml")
    assert 0.25 in mat.orbit.ratio_list
    assert 0.25 not in shipped.orbit.ratio_list


def test_init_refuses_an_existing_configuration(lab):
    done = orbitrig("init", str(lab), timeout=60, cwd=lab.parent, columns=None)  # from the lab fixture's folder
    assert done.returncode == 2, done.stderr
    assert f"{lab / 'rig.toml'}: already there" in done.stderr
    assert "Traceback" not in done.stderr
    assert "lab rig" in (lab / "rig.toml").read_text()  # untouched
    write_lab(lab, force=True)
    assert "lab rig" not in (lab / "rig.toml").read_text()


@pytest.mark.parametrize("force", [(), ("--force",)])
def test_init_into_a_file_says_it_is_not_a_folder(tmp_path, force):
    """It said `DIR/rig.toml: cannot write: File exists`, of a rig.toml nobody had written."""
    a_file = tmp_path / "notes.txt"
    a_file.write_text("kept")
    done = orbitrig("init", str(a_file), *force, timeout=60, columns=None)
    assert done.returncode == 2, done.stderr
    assert (
        done.stderr
        == f"orbitrig init: error: {a_file}: not a folder (a file is there): give a new or existing folder for the lab\n"
    )
    assert a_file.read_text() == "kept"


def test_broker_dir_goes_into_mosquitto_conf(tmp_path):
    write_lab(tmp_path / "lab", broker_dir=Path("/etc/mosquitto/orbitrig"))
    conf = (tmp_path / "lab" / "mosquitto" / "mosquitto.conf").read_text()
    assert "password_file /etc/mosquitto/orbitrig/passwd\n" in conf
    assert "acl_file /etc/mosquitto/orbitrig/acl\n" in conf
    assert "#cafile /etc/mosquitto/orbitrig/ca.crt\n" in conf


def test_init_broker_configuration_runs_mosquitto(lab):
    """The written mosquitto.conf, its listeners moved to free ports: the broker starts with
    the lab's password file and ACL, a viewer may read and may not command."""
    broker = lab / "mosquitto"
    private_copy(broker / "passwd.example", broker / "passwd")
    conf, _, people = on_free_ports((broker / "mosquitto.conf").read_text())
    (broker / "test.conf").write_text(AS_ROOT + conf)
    proc = launch_mosquitto(broker / "test.conf", broker / "mosquitto.log", people)
    try:
        pub = ["mosquitto_pub", "-h", "127.0.0.1", "-p", str(people), "-t", "orbitrig/lab/cmd", "-m", "{}", "-q", "1"]
        ok = subprocess.run(pub + ["-u", "operator", "-P", ACCOUNTS["operator"]], capture_output=True, timeout=10)
        bad = subprocess.run(pub + ["-u", "operator", "-P", "wrong"], capture_output=True, timeout=10)
        assert ok.returncode == 0, ok.stderr
        assert bad.returncode != 0
        assert (broker / "data").is_dir()
    finally:
        end_process(proc)


def test_init_writes_the_rig_id_given_and_reminds_when_none_is(tmp_path):
    def init(*args):
        return orbitrig("init", *args, timeout=60, columns=None)

    own = init(str(tmp_path / "b"), "--rig-id", "SAC-DS-2")
    assert own.returncode == 0, own.stderr
    assert cfg.load_rig(tmp_path / "b" / "rig.toml").rig_id == "SAC-DS-2"
    assert "note: rig_id" not in own.stderr
    said = " ".join(own.stdout.split())  # the last line: what to edit and how commands find it
    assert said.endswith(
        f"lab configuration in {tmp_path / 'b'}: edit rig.toml (its [transports], channels, [bearing] and [drives]"
        " are the paper's rig's until you do; `orbitrig calibrate` steps then measure its calibration); commands"
        f" use it when run in this folder, with ORBITRIG_HOME={(tmp_path / 'b').resolve()}, or with --config"
        f" {tmp_path / 'b' / 'rig.toml'}"
    ), said
    shipped = init(str(tmp_path / "a"))
    assert shipped.returncode == 0, shipped.stderr
    assert cfg.load_rig(tmp_path / "a" / "rig.toml").rig_id == "SAC-DS-1"
    assert "note: rig_id in rig.toml is the shipped example's (SAC-DS-1)" in shipped.stderr
    bad = init(str(tmp_path / "c"), "--rig-id", "two words")
    assert bad.returncode == 2 and "--rig-id: 'two words'" in bad.stderr and "Traceback" not in bad.stderr
    assert not (tmp_path / "c" / "rig.toml").exists()


@pytest.mark.parametrize("broker_dir", [None, "/etc/mosquitto/orbitrig"])
def test_init_broker_readme_names_the_files_mosquitto_conf_uses(tmp_path, broker_dir):
    """The lab's mosquitto/README.md tells to make the very password file its mosquitto.conf reads:
    in the lab folder (a path with a space, quoted for the shell), or in --broker-dir."""
    import shlex

    lab = tmp_path / "my lab"
    done = orbitrig("init", str(lab), *(["--broker-dir", broker_dir] if broker_dir else []), timeout=60, columns=None)
    assert done.returncode == 0, done.stderr
    conf = (lab / "mosquitto" / "mosquitto.conf").read_text()
    passwd = next(line.split(" ", 1)[1] for line in conf.splitlines() if line.startswith("password_file "))
    assert passwd == str(Path(broker_dir or lab / "mosquitto").resolve() / "passwd")
    readme = (lab / "mosquitto" / "README.md").read_text()
    commands = [shlex.split(line) for line in readme.splitlines() if line.strip().startswith("mosquitto_passwd ")]
    assert len(commands) == 4
    assert [c[-2] for c in commands] == [passwd] * 4  # mosquitto_passwd [-c] FILE USER
    chown, chown_data = [shlex.split(line) for line in readme.splitlines() if line.strip().startswith("chown ")]
    assert [w for w in chown if "passwd" in w] == [passwd, passwd]
    data = next(line.split(" ", 1)[1] for line in conf.splitlines() if line.startswith("persistence_location "))
    assert (
        chown_data == ["chown", "mosquitto:", data]
        and data == str(Path(broker_dir or lab / "mosquitto").resolve() / "data") + "/"
    )
    if broker_dir is None:
        assert "/etc/mosquitto" not in readme
    acl = next(line.split(" ", 1)[1] for line in conf.splitlines() if line.startswith("acl_file "))
    assert f"copy `acl` to {shlex.quote(acl)}" in readme  # where the conf reads it
    back = readme.replace(shlex.quote(passwd), "/etc/mosquitto/orbitrig/passwd")
    back = back.replace(shlex.quote(acl), "/etc/mosquitto/orbitrig/acl")
    back = back.replace(shlex.quote(data), "/var/lib/mosquitto/")
    assert back == (REPO / "config" / "mosquitto" / "README.md").read_text()  # the shipped text otherwise


def test_init_dates_the_labs_initial_record_when_it_writes_it(tmp_path):
    """The lab's initial record is dated (and named) when `orbitrig init` writes it, not at the
    shipped example's date, which made a new lab's calibration look older than the lab; it says
    so in its header and in `calibrate show`, is sealed as written, and rig.toml makes it active."""
    import datetime as dt

    from rigunits import seconds_since

    write_lab(tmp_path / "lab", rig_id="LAB-7")
    rig = cfg.load_rig(tmp_path / "lab" / "rig.toml")
    (path,) = (tmp_path / "lab" / "calibration").glob("*-initial.toml")
    assert rig.calibration_record == path.stem and rig.record.step == "initial"
    age = seconds_since(rig.record.date)
    assert age is not None and 0 <= age < 60, rig.record.date
    assert path.stem == f"{dt.datetime.fromisoformat(rig.record.date):%Y-%m-%dT%H%M%S}Z-initial"
    assert (rig.record.operator, rig.record.rig) == ("orbitrig init", "LAB-7")
    assert f"# `orbitrig init` on {rig.record.date[:10]} when the lab folder was made" in path.read_text()
    shown = orbitrig("calibrate", "show", "--config", str(tmp_path / "lab" / "rig.toml"), timeout=60, columns=None)
    assert shown.returncode == 0, shown.stderr
    assert (
        f"# initial record: nothing measured yet; dated {rig.record.date[:10]}, when it was written "
        "(operator: orbitrig init), not when anything was calibrated"
    ) in shown.stdout
    assert "# as written (its sha256 line matches its text)" in shown.stdout


def test_init_force_within_the_same_second_writes_a_later_initial_record(tmp_path):
    """`init --force` in the second of the last init stopped on "a record of that name exists
    already" (records are named to the second and never written over): it now dates its initial
    record at the next free second; the earlier records stay as they were."""
    import datetime as dt

    from rigunits import record_stamp

    folder = tmp_path / "lab"
    write_lab(folder)
    (first,) = (folder / "calibration").glob("*-initial.toml")
    now = dt.datetime.now(dt.timezone.utc)
    taken = [f"{record_stamp(now + dt.timedelta(seconds=s))}-initial" for s in (0, 1)]
    for name in taken:  # this second's and the next's names are taken
        if not (folder / "calibration" / f"{name}.toml").exists():
            (folder / "calibration" / f"{name}.toml").write_bytes(first.read_bytes())
    before = {p.name: p.read_bytes() for p in (folder / "calibration").glob("*.toml")}
    write_lab(folder, force=True, rig_id="LAB-8")
    rig = cfg.load_rig(folder / "rig.toml")
    assert rig.calibration_record > max(taken) and rig.record.rig == "LAB-8"
    assert {n: (folder / "calibration" / n).read_bytes() for n in before} == before
