"""Real parts for the MQTT tests: a mosquitto broker with a password file and
the project's example ACL, independent clients (mosquitto_pub / mosquitto_sub)
and the `orbitrig serve` process."""

from __future__ import annotations

import asyncio
import contextlib
import json
import re
import shutil
import signal
import socket
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from .cli_helpers import ended, orbitrig_cmd, started
from .paths import ROOT
from .polling import until
from .ports import free_port, wait_port


if TYPE_CHECKING:
    from orbitrig.service.rig_service import RigService

REPO = ROOT  # the source tree
EXAMPLE_ACL = REPO / "config" / "mosquitto" / "acl"
EXAMPLE_PASSWD = REPO / "config" / "mosquitto" / "passwd.example"
EXAMPLE_CONF = REPO / "config" / "mosquitto" / "mosquitto.conf"
MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"

#: The accounts of the example ACL and the passwords the tests give them.
ACCOUNTS = {
    "orbitrig-service": "svc-secret",
    "orbitrig-service-abort": "svc-secret",  # the service's abort connection: the same password
    "operator": "op-secret",
    "viewer": "view-secret",
}


#: The first line of a test broker's configuration: mosquitto started as root keeps root's
#: rights (it would drop to the `mosquitto` user and lose the test's files, root's alone).
AS_ROOT = "user root\n"


def private_copy(source: Path, target: Path) -> Path:
    """``source`` copied to ``target``, readable by its owner only (mosquitto 2 warns about a
    password file others can read); returns ``target``."""
    shutil.copyfile(source, target)
    target.chmod(0o600)
    return target


def on_free_ports(conf: str) -> tuple[str, int, int]:
    """A lab's mosquitto.conf (`orbitrig init`) with its two listeners (the service's, 1883, and
    the people's, 1884) moved to free ports: (text, service port, people's port)."""
    service, people = free_port(), free_port()
    text = re.sub(r"(?m)^listener 1883 ", f"listener {service} ", conf)
    text = re.sub(r"(?m)^listener 1884 ", f"listener {people} ", text)
    assert text.count(f"listener {service} ") == 1 and text.count(f"listener {people} ") == 1, conf
    return text, service, people


def launch_mosquitto(conf: Path, log: Path, *ports: int) -> subprocess.Popen:
    """mosquitto on ``conf``, its output appended to ``log``, once it listens on every one of
    ``ports`` (within 30 s: milliseconds on idle cores, a loaded host's process start included);
    if it does not, it is ended and the error carries its log."""
    with open(log, "ab") as out:
        proc = subprocess.Popen([MOSQUITTO, "-c", str(conf)], stdout=out, stderr=out)
    try:
        for port in ports:
            wait_port(port, timeout=30.0)
    except TimeoutError:
        end_process(proc)
        raise RuntimeError(f"mosquitto did not start:\n{log.read_text(errors='replace')}") from None
    return proc


def end_process(proc: subprocess.Popen) -> None:
    """SIGTERM, and SIGKILL if it has not ended within 5 s."""
    ended(proc, signal.SIGTERM, 5)


def make_test_ca(folder: Path) -> Path:
    """A throw-away CA and a server certificate for 127.0.0.1 (openssl); returns the CA file."""

    def ssl(*args: str) -> None:
        subprocess.run(["openssl", *args], cwd=folder, check=True, capture_output=True)

    ssl(
        "req",
        "-x509",
        "-newkey",
        "rsa:2048",
        "-nodes",
        "-days",
        "2",
        "-subj",
        "/CN=orbitrig test CA",
        "-keyout",
        "ca.key",
        "-out",
        "ca.crt",
    )
    ssl("req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=127.0.0.1", "-keyout", "server.key", "-out", "server.csr")
    (folder / "san.ext").write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    ssl(
        "x509",
        "-req",
        "-in",
        "server.csr",
        "-CA",
        "ca.crt",
        "-CAkey",
        "ca.key",
        "-CAcreateserial",
        "-days",
        "2",
        "-extfile",
        "san.ext",
        "-out",
        "server.crt",
    )
    return folder / "ca.crt"


def client_id_lines() -> tuple[list[str], list[str]]:
    """The shipped config's client-id binding: (global lines, service-listener lines)."""
    lines = [ln.strip() for ln in EXAMPLE_CONF.read_text().splitlines()]
    glob = [ln for ln in lines if ln.split(" ")[0] in ("clientid_prefixes", "auto_id_prefix")]
    listener = [ln for ln in lines if ln.startswith("use_username_as_clientid")]
    assert glob and listener, "config/mosquitto/mosquitto.conf lost its client-id binding"
    return glob, listener


def flow_limit_lines() -> list[str]:
    """The shipped config's queue and in-flight limits (every test broker has them)."""
    keys = ("max_inflight_messages", "max_queued_messages", "queue_qos0_messages")
    lines = [ln.strip() for ln in EXAMPLE_CONF.read_text().splitlines() if ln.split(" ")[0] in keys]
    assert len(lines) == len(keys), "config/mosquitto/mosquitto.conf lost its flow limits"
    return lines


class Broker:
    """mosquitto on a loopback port: no anonymous access, a password file made
    with mosquitto_passwd, config/mosquitto/acl (the shipped example) and the
    shipped config's flow limits.

    ``bind_ids``: also the shipped config's client-id binding, with the rig
    service's own listener on ``service_port`` (``service_url``); ``persist``:
    sessions and retained messages survive a restart."""

    def __init__(
        self,
        workdir: Path,
        port: int | None = None,
        *,
        tls: bool = False,
        bind_ids: bool = False,
        persist: bool = False,
    ):
        self.dir = Path(workdir)
        self.tls = tls
        self.dir.mkdir(parents=True, exist_ok=True)
        self.port = port or free_port()
        self.service_port = free_port() if bind_ids else self.port
        # the shipped example password file: ACCOUNTS are its passwords
        self.passwd = private_copy(EXAMPLE_PASSWD, self.dir / "passwd")
        tls_lines = ""
        if tls:
            self.ca = make_test_ca(self.dir)
            tls_lines = f"cafile {self.ca}\ncertfile {self.dir / 'server.crt'}\nkeyfile {self.dir / 'server.key'}\n"
        ids, service_listener = client_id_lines() if bind_ids else ([], [])
        if bind_ids:
            service_listener = [f"listener {self.service_port} 127.0.0.1", *service_listener, ""]
        persistence = f"persistence true\npersistence_location {self.dir}/\n" if persist else "persistence false\n"
        self.conf = self.dir / "mosquitto.conf"
        self.conf.write_text(
            AS_ROOT + "per_listener_settings false\n"
            "allow_anonymous false\n"
            f"password_file {self.passwd}\n"
            f"acl_file {EXAMPLE_ACL}\n"
            + "".join(f"{ln}\n" for ln in flow_limit_lines())
            + "".join(f"{ln}\n" for ln in ids)
            + "\n".join(service_listener)
            + f"listener {self.port} 127.0.0.1\n"
            f"{tls_lines}"
            f"{persistence}"
            "log_dest stderr\n"
            "log_type error\nlog_type warning\nlog_type notice\nlog_type information\n"
        )
        self.log = self.dir / "mosquitto.log"
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"{'mqtts' if self.tls else 'mqtt'}://127.0.0.1:{self.port}"

    @property
    def service_url(self) -> str:
        """Where the rig service connects (the service listener with ``bind_ids``)."""
        return f"{'mqtts' if self.tls else 'mqtt'}://127.0.0.1:{self.service_port}"

    def start(self) -> None:
        self.proc = launch_mosquitto(self.conf, self.log, self.port, self.service_port)

    def stop(self) -> None:
        """Ends the broker (a test may stop it before its end, to take it away from a client)."""
        if self.proc is not None:
            end_process(self.proc)
        self.proc = None

    def __enter__(self) -> "Broker":
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def client_args(self, user: str | None, port: int | None = None) -> list[str]:
        args = ["-h", "127.0.0.1", "-p", str(port or self.port)]
        if self.tls:
            args += ["--cafile", str(self.ca)]
        if user is not None:
            args += ["-u", user, "-P", ACCOUNTS[user]]
        return args

    def pub(
        self,
        topic: str,
        payload: str | bytes,
        *,
        user: str | None = "operator",
        qos: int = 1,
        version: int | None = None,
        retain: bool = False,
    ) -> subprocess.CompletedProcess:
        """Publish one message with mosquitto_pub (payload from standard input)."""
        args = ["mosquitto_pub", *self.client_args(user), "-q", str(qos), "-t", topic, "-s"]
        if version:
            args += ["-V", str(version)]
        if retain:
            args.append("-r")
        data = payload.encode() if isinstance(payload, str) else payload
        return subprocess.run(args, input=data, capture_output=True, timeout=10)


def broker_fixture(*, bind_ids: bool = False, name: str | None = None):
    """A module's broker as a pytest fixture (``broker = broker_fixture()`` in a conftest or a test
    module): started once for the module, stopped after its last test. ``bind_ids``: with the
    shipped config's client-id binding (the rig service on ``service_url``)."""
    import pytest  # here: the benches use this module without pytest

    @pytest.fixture(scope="module", name=name)
    def module_broker(tmp_path_factory):
        with Broker(tmp_path_factory.mktemp("broker"), bind_ids=bind_ids) as b:
            yield b

    return module_broker


def retained(broker: "Broker", topic: str, user: str = "viewer", wait: float = 10.0) -> "Msg | None":
    """The retained message on ``topic`` now (a fresh subscription), or None once ``wait`` s (whole
    seconds, at least 1; mosquitto_sub's start and connection included) passed without one. A
    retained message comes at once: the default wait is for a loaded host; a test that expects
    None passes a short one."""
    done = subprocess.run(
        [
            "mosquitto_sub",
            *broker.client_args(user),
            "-t",
            topic,
            "-q",
            "1",
            "--retained-only",
            "-C",
            "1",
            "-W",
            str(int(max(1, wait))),
            "-F",
            "%j",
        ],
        capture_output=True,
        timeout=wait + 10,
    )
    line = done.stdout.decode("utf-8", "surrogateescape").strip()
    if not line:
        return None
    obj = json.loads(line)
    return Msg(
        obj["topic"],
        (obj["payload"] or "").encode("utf-8", "surrogateescape"),  # null: an empty message
        obj["qos"],
        bool(obj["retain"]),
        time.monotonic(),
    )


@dataclass
class Msg:
    topic: str
    payload: bytes
    qos: int
    retain: bool
    t: float  # time.monotonic() when read

    def json(self) -> Any:
        return json.loads(self.payload)


@dataclass
class Watcher:
    """mosquitto_sub in the background, collecting every message it prints; constructed once the
    broker has acknowledged its subscription (nothing published after that is missed)."""

    broker: Broker
    topic: str | tuple[str, ...]  # one filter or several
    user: str | None = "viewer"
    messages: list[Msg] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._cond = threading.Condition()
        self._subscribed = False
        filters = [self.topic] if isinstance(self.topic, str) else list(self.topic)
        self.proc = subprocess.Popen(
            [
                "stdbuf",
                "-oL",  # its debug lines reach the pipe as they are printed (coreutils)
                "mosquitto_sub",
                *self.broker.client_args(self.user),
                "-d",  # its SUBACK line says when the subscription holds (messages are JSON lines)
                "-q",
                "1",
                *(a for t in filters for a in ("-t", t)),
                "-F",
                "%j",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()
        self._wait_subscribed(10.0)

    def _wait_subscribed(self, timeout: float) -> None:
        """Return once the broker has acknowledged the subscription (or refused the client: the
        process ended), so that nothing published after the Watcher exists is missed."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not self._subscribed and self.proc.poll() is None:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"mosquitto_sub on {self.topic} not subscribed within {timeout} s")
                self._cond.wait(min(left, 0.1))

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if not line.startswith(b"{"):  # a debug line of -d
                if b"received SUBACK" in line:
                    with self._cond:
                        self._subscribed = True
                        self._cond.notify_all()
                continue
            obj = json.loads(line.decode("utf-8", "surrogateescape"))
            msg = Msg(
                obj["topic"],
                (obj["payload"] or "").encode("utf-8", "surrogateescape"),  # null: an empty message
                obj["qos"],
                bool(obj["retain"]),
                time.monotonic(),
            )
            with self._cond:
                self.messages.append(msg)
                self._cond.notify_all()

    def wait_for(
        self, pred: Callable[[Msg], bool], timeout: float = 10.0, *, start: int = 0, what: str = "a message"
    ) -> Msg:
        """First message (from index ``start``) matching ``pred``."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for msg in self.messages[start:]:
                    if pred(msg):
                        return msg
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    seen = "\n".join(f"  {m.topic} {m.payload[:200]!r}" for m in self.messages[-15:])
                    raise AssertionError(f"no {what} within {timeout} s; last messages:\n{seen}")
                self._cond.wait(min(left, 0.2))

    def on(self, suffix: str, start: int = 0) -> list[Msg]:
        with self._cond:
            return [m for m in self.messages[start:] if m.topic.endswith("/" + suffix)]

    def mark(self) -> int:
        with self._cond:
            return len(self.messages)

    def close(self) -> None:
        """Ends the subscriber: SIGTERM, and SIGKILL if it has not gone within 10 s (a starved
        machine; its broker may have gone first, leaving it in a reconnect)."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self._thread.join(5)


#: wall s a `serve --sim` may take from its start to its first status: 4 s on idle cores, 28-30 s
#: with five CPU hogs per core on 2 cores (load 12-15): the CPU of its imports and of its simulator
#: process's, shared with the hogs, which it waited 30 s for; twice that, so that a start-up that
#: hangs (a simulator that does not announce itself, a broker that does not answer) still fails
SERVE_START_S = 60.0


class RigClient:
    """An operator (publishing commands) plus a viewer (watching the rig's topics)."""

    def __init__(self, broker: Broker, rig_id: str, service: "Service | None" = None, watch: tuple[str, ...] = ("#",)):
        self.broker = broker
        self.service = service  # its log is shown when a wait fails
        self.prefix = f"orbitrig/{rig_id}"
        self.watch = Watcher(broker, tuple(f"{self.prefix}/{t}" for t in watch))
        self._n = 0

    def send(
        self, obj: dict | str | bytes, *, user: str = "operator", cid: str | None = None, version: int | None = None
    ) -> str:
        """Publish a command; a dict without ``id`` gets a fresh one. Returns the id."""
        if isinstance(obj, dict):
            obj = dict(obj)
            if "id" not in obj:
                self._n += 1
                obj["id"] = cid or f"t{self._n}-{obj.get('cmd')}"
            cid = obj["id"]
            obj = json.dumps(obj)
        done = self.broker.pub(f"{self.prefix}/cmd", obj, user=user, version=version)
        assert done.returncode == 0, done.stderr
        self.last_pub = done
        return cid

    def _wait(self, pred: Callable[[Msg], bool], timeout: float, start: int, what: str) -> Msg:
        try:
            return self.watch.wait_for(pred, timeout, start=start, what=what)
        except AssertionError as err:
            if self.service is None:
                raise
            raise AssertionError(f"{err}\n--- serve log (tail) ---\n{self.service.text()[-3000:]}") from None

    def reply(self, cid: str | None, timeout: float = 10.0, start: int = 0) -> dict:
        msg = self._wait(
            lambda m: m.topic == f"{self.prefix}/reply" and m.json().get("id") == cid,
            timeout,
            start,
            f"reply to {cid!r}",
        )
        assert msg.qos == 1
        return msg.json()

    def command(self, obj: dict, timeout: float = 10.0) -> dict:
        mark = self.watch.mark()
        cid = self.send(obj)
        return self.reply(cid, timeout, start=mark)

    def ready(self, state: str | Callable[[dict], bool] = "idle") -> dict:
        """The service's first status `state` (any status: ``lambda s: True``), as it starts: waited
        for SERVE_START_S."""
        return self.status(state, timeout=SERVE_START_S)

    def status(self, state: str | Callable[[dict], bool], timeout: float = 30.0, start: int = 0) -> dict:
        pred = (lambda s: s["state"] == state) if isinstance(state, str) else state
        msg = self._wait(
            lambda m: m.topic == f"{self.prefix}/status" and pred(m.json()), timeout, start, f"status {state}"
        )
        assert msg.qos == 1
        return msg.json()

    def close(self) -> None:
        self.watch.close()


class Service:
    """`orbitrig serve` as a subprocess (its log in ``log``), behind ``launcher`` if given (e.g.
    sim_endpoints_spy.py, to reach its simulator's control API)."""

    def __init__(
        self, args: list[str], workdir: Path, env: dict[str, str] | None = None, launcher: tuple[str, ...] = ()
    ):
        self.log, self.workdir = Path(workdir) / "serve.log", workdir
        self.cmd, self.env = [*launcher, *orbitrig_cmd("serve", *args)], {"PYTHONUNBUFFERED": "1", **(env or {})}
        self.proc = self._started()

    def _started(self) -> subprocess.Popen:
        with open(self.log, "ab") as log:
            return started(self.cmd, cwd=self.workdir, env=self.env, stdin=None, stdout=log, stderr=log)

    def restart(self) -> None:
        """The service ended (Ctrl-C, as `stop`; nothing if it already has) and started again with the
        same arguments, its output appended to the same log."""
        self.stop()
        self.proc = self._started()

    def text(self) -> str:
        return self.log.read_text(errors="replace")

    def kill(self, sig: int = signal.SIGKILL) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        self.proc.wait(20)

    def stop(self) -> int:
        return interrupt(self.proc)


def interrupt(proc: subprocess.Popen) -> int:
    """Ctrl-C a process of ours (SIGINT), kill it if it has not ended within 20 s; its exit status."""
    return ended(proc, signal.SIGINT, 20)


async def wait(fn, *args, **kw):
    """``fn(*args, **kw)`` (a blocking client call) in a thread, the loop serving meanwhile."""
    return await asyncio.to_thread(fn, *args, **kw)


@contextlib.asynccontextmanager
async def serving(service: RigService):
    """An in-process RigService serving (its task) once its main connection is up; stopped on the way out."""
    stop = asyncio.Event()
    task = asyncio.create_task(service.serve(stop))
    try:
        await until(lambda: service.link.online.is_set(), 30, "the service connected")
        yield task
    finally:
        stop.set()
        await asyncio.wait_for(task, 30)


# -- test matrices (small and fast on the simulator) ----------------------------

MATRIX = """\
name = "{name}"
revolutions = {revs}
settle_hold_s = 0.1

[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]

[orbit]
ratios = {ratios}
directions = {directions}

[[models]]
model = "kc7"
"""


def run_dirs(runs: Path) -> list[Path]:
    """The run directories in a service's runs folder, by name (not its ``.run-ids``, where each
    run's id is taken: orbitrig.store.identity)."""
    return sorted(p for p in runs.iterdir() if not p.name.startswith("."))


def write_matrices(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "quick.toml").write_text(
        MATRIX.format(name="quick", revs=10, ratios="[0.5, 0.8]", directions='["forward", "backward"]')
    )
    (folder / "long.toml").write_text(
        MATRIX.format(
            name="long",
            revs=60,
            ratios="[0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.2]",
            directions='["forward", "backward"]',
        )
    )
    # judged fits: a frequency-dependent model (adequacy) and one the data cannot identify (refused)
    (folder / "judged.toml").write_text(
        MATRIX.format(name="judged", revs=10, ratios="[0.3, 0.6, 0.9, 1.2]", directions='["forward", "backward"]')
        + '\n[[models]]\nmodel = "kc7"\nfreq_dep = "power:1"\n\n[[models]]\nmodel = "kcd12"\nfreq_dep = "poly:4"\n'
    )
    return folder


class CutProxy:
    """A TCP relay 127.0.0.1:port -> target port that the test can cut: ``cut()``
    closes every relayed connection and refuses new ones (accept, close) until
    ``restore()``. The client behind it sees its link to the broker drop while
    the broker stays up for everyone else."""

    def __init__(self, target_port: int, *, lifetime: float | None = None):
        self.target = target_port
        self.lifetime = lifetime  # s after which each relayed connection is cut
        self.server = socket.socket()
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(16)
        self.port = self.server.getsockname()[1]
        self.open = True
        self.accepted = 0
        self._pairs: list[tuple[socket.socket, socket.socket]] = []
        self._lock = threading.Lock()
        self._closed = False
        threading.Thread(target=self._accept, daemon=True).start()

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def _accept(self) -> None:
        while not self._closed:
            try:
                conn, _ = self.server.accept()
            except OSError:
                return
            self.accepted += 1
            if not self.open:
                conn.close()
                continue
            up = socket.create_connection(("127.0.0.1", self.target))
            with self._lock:
                self._pairs.append((conn, up))
            self._relay(conn, up)
            if self.lifetime is not None:
                threading.Timer(self.lifetime, self._drop, args=((conn, up),)).start()

    def _relay(self, client: socket.socket, broker: socket.socket) -> None:
        """Pass the bytes each way between an accepted connection and its own to the target
        (a subclass that reads or holds them overrides this)."""
        for a, b in ((client, broker), (broker, client)):
            threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    @staticmethod
    def _pump(src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(65536):
                dst.sendall(data)
        except OSError:
            pass
        for s in (src, dst):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def cut(self) -> None:
        self.open = False
        with self._lock:
            pairs, self._pairs = self._pairs, []
        for pair in pairs:
            self._drop(pair)

    @staticmethod
    def _drop(pair: tuple[socket.socket, socket.socket]) -> None:
        for s in pair:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()

    def restore(self) -> None:
        self.open = True

    def close(self) -> None:
        self._closed = True
        self.cut()
        self.server.close()


def service_password_file(work: Path) -> Path:
    """``work``/service.pw: the account orbitrig-service's password, readable by its owner only
    (the service refuses a password file others can read)."""
    pw = work / "service.pw"
    pw.write_text(ACCOUNTS["orbitrig-service"] + "\n")
    pw.chmod(0o600)
    return pw


def sim_service(url: str, rig: str, work: Path) -> Service:
    """`orbitrig serve` on the simulator (sim_service_args) with the service's password file."""
    return Service(sim_service_args(url, rig, work, "--password-file", str(service_password_file(work))), work)


def two_pressures(name: str) -> str:
    """The test MATRIX named `name` with two points differing in the recess pressure only (0.4826
    and 0.6895 MPa, the operator sets each by hand: the drives keep turning), 10 revolutions a
    block, orbit ratios 0.5 and 0.8 forward."""
    return MATRIX.format(name=name, revs=10, ratios="[0.5, 0.8]", directions='["forward"]').replace(
        "recess_pressure_mpa = [0.4826]", "recess_pressure_mpa = [0.4826, 0.6895]"
    )


def serving_sim(broker: Broker, tmp_path_factory, rig: str, **matrices: str):
    """A module fixture's generator (``yield from``): `sim_service` for `rig` in a fresh folder, its
    matrix folder holding ``matrices`` (name: TOML text) besides the test ones; stopped at the end
    (exit 0)."""
    work = tmp_path_factory.mktemp("serve")
    (work / "matrices").mkdir()
    for name, text in matrices.items():
        (work / "matrices" / f"{name}.toml").write_text(text)
    svc = sim_service(broker.url, rig, work)
    yield svc
    assert svc.stop() == 0, svc.text()[-3000:]


def sim_service_args(url: str, rig: str, work: Path, *extra: str, speedup: float = 20) -> list[str]:
    """`orbitrig serve` arguments of a service on the simulator as the account orbitrig-service:
    broker `url`, rig id, the test matrices (write_matrices) and the runs under `work`."""
    return [
        "--sim",
        "--broker",
        url,
        "--rig-id",
        rig,
        "--username",
        "orbitrig-service",
        "--matrices",
        str(write_matrices(work / "matrices")),
        "--out",
        str(work / "runs"),
        "--speedup",
        f"{speedup:g}",
        *extra,
    ]


@contextlib.asynccontextmanager
async def serving_unsupervised(broker: Broker, work: Path, rig_id: str, policy: str, **kw):
    """(service, sim_rig): `unsupervised_service` (``kw``: rig, confirm) on a fresh simulator
    (speed-up 20), serving, subscribed to its commands; on the way out it stops, any run aborted first (the drives stop
    before the simulator closes)."""
    from sim.rig import SimRig

    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        service = unsupervised_service(broker, work, rig_id, policy, sim_rig, **kw)
        stop = asyncio.Event()
        serving = asyncio.create_task(service.serve(stop))
        try:
            await _subscribed(service, serving)
            yield service, sim_rig
        finally:
            stop.set()
            service.abort_run("test over")
            await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 60)


async def _subscribed(service, serving: asyncio.Task, timeout: float = 60.0) -> None:
    """Until the service has subscribed to its commands (a command sent before is lost: QoS 1 is
    kept for a subscription, not for a topic), or raise why it did not."""
    online = asyncio.create_task(service.link.online.wait())
    done, _ = await asyncio.wait([online, serving], timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
    if online not in done:
        online.cancel()
        if serving.done():
            serving.result()
        raise AssertionError(f"the service did not subscribe within {timeout:g} s")


def unsupervised_service(broker: Broker, work: Path, rig_id: str, policy: str, sim_rig, *, rig=None, confirm="auto"):
    """The service `orbitrig serve --sim` builds (in process, on `sim_rig`) with supervision
    `policy` after 1 s without the broker and quick reconnects; `rig` (default: the shipped one)."""
    from orbitrig.cli.serve import build_service
    from orbitrig.config import load_rig
    from orbitrig.service.rig_service import BrokerSettings, ServiceSettings

    settings = ServiceSettings(
        rig_id=rig_id,
        matrices_dir=write_matrices(work / "matrices"),
        supervision_policy=policy,
        supervision_timeout=1.0,
        reconnect_initial=0.2,
        reconnect_max=1.0,
    )
    creds = BrokerSettings.from_url(broker.url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"])
    return build_service(rig or load_rig(), settings, creds, out=work / "runs", sim_rig=sim_rig, confirm=confirm)


def engineless_service(url: str, work: Path, rig_id: str, **settings):
    """A RigService on the broker at `url` (as orbitrig-service) that runs nothing: no engine is
    built and no matrix loaded; `settings`: more ServiceSettings fields."""
    from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings

    return RigService(
        ServiceSettings(rig_id=rig_id, matrices_dir=write_matrices(work / "m"), **settings),
        BrokerSettings.from_url(url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"]),
        engine_factory=lambda name, m: None,
        load_matrix=lambda p: None,
    )


def endpoint_lines(sim_rig) -> dict[str, str]:
    """The [transports] lines of a rig.toml naming the simulator `sim_rig`'s endpoints."""
    return {
        "modbus_url": f'modbus_url = "{sim_rig.modbus_url}"',
        "adc_url": f'adc_url = "{sim_rig.adc_url}"',
        "can_channel": f'can_channel = "{sim_rig.can_channel}"',
        "can_interface": 'can_interface = "virtual"',
    }


def service_in_process(
    url: str, work: Path, rig_id: str, *, rig=None, sim_rig=None, abort: bool = True, reload=None, **settings
) -> "RigService":
    """The service `orbitrig serve` builds (orbitrig.cli.serve.build_service), in process, on the
    broker at `url` under the shipped service account (`abort`: with its abort connection's), the
    test matrices in `work`/matrices, runs in `work`/runs; on `sim_rig` (steps confirmed at once)
    or, without one, on the drives of `rig` (default: the shipped rig.toml); `settings`: further
    ServiceSettings fields (reconnect_initial, shutdown_timeout, ...)."""
    from orbitrig.cli.serve import build_service
    from orbitrig.config import load_rig
    from orbitrig.service.rig_service import BrokerSettings, ServiceSettings
    from orbitrig.service.settings import AbortAccount

    account = AbortAccount("orbitrig-service-abort", ACCOUNTS["orbitrig-service-abort"]) if abort else None
    creds = BrokerSettings.from_url(
        url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"], abort=account
    )
    service_settings = ServiceSettings(rig_id=rig_id, matrices_dir=write_matrices(work / "matrices"), **settings)
    sim = {"sim_rig": sim_rig, "confirm": "auto"} if sim_rig is not None else {}
    return build_service(rig or load_rig(), service_settings, creds, out=work / "runs", reload=reload, **sim)
