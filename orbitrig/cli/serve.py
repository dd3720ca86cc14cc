"""`orbitrig serve`: the rig service under MQTT control (docs/protocols/mqtt.md). The rig
configuration and its active calibration record are loaded again at each start of a run.
Its options and the broker accounts made of them: orbitrig.cli.serve_options."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from orbitrig.cli import serve_options as o
from orbitrig.cli.serve_options import ServeOptions, fail
from orbitrig.cli.service_log import DEFAULT_BACKUPS, DEFAULT_MAX_MB, setup_service_log
from orbitrig.run.states import ConfirmMode
from orbitrig.service.settings import DEFAULT_RIG_ID, SUPERVISION_TIMEOUT_S, SupervisionPolicy

if TYPE_CHECKING:  # imported where used: `orbitrig serve --help` stays light
    from orbitrig.service.rig_service import RigService


def register(app: typer.Typer) -> None:
    @app.command("serve")
    def serve(
        broker: o.BrokerOpt,
        sim: o.SimOpt = False,
        sim_config: o.SimConfigOpt = None,
        config: o.ConfigOpt = None,
        rig_id: o.RigIdOpt = DEFAULT_RIG_ID,
        prefix: o.PrefixOpt = None,
        username: o.UsernameOpt = None,
        password_file: o.PasswordFileOpt = None,
        abort_username: o.AbortUserOpt = None,
        abort_password_file: o.AbortPasswordFileOpt = None,
        abort_connection: o.AbortConnectionOpt = True,
        tls_ca: o.TlsCaOpt = None,
        out: o.OutOpt = Path("runs"),
        matrices: o.MatricesOpt = None,
        supervision_policy: o.PolicyOpt = SupervisionPolicy.KEEP,
        supervision_timeout: o.TimeoutOpt = SUPERVISION_TIMEOUT_S,
        client_id: o.ClientIdOpt = None,
        confirm: o.ConfirmOpt = ConfirmMode.REMOTE,
        speedup: o.SpeedupOpt = None,
        verbose: o.VerboseOpt = False,
        catalog: o.CatalogOpt = None,
        draw_figures: o.DrawFigures = True,
        log_file: o.LogFileOpt = None,
        log_max_mb: o.LogMbOpt = DEFAULT_MAX_MB,
        log_backups: o.LogBackupsOpt = DEFAULT_BACKUPS,
    ) -> None:
        """Run the rig service: start, watch and stop runs over MQTT."""
        _start(ServeOptions(**locals()))


def _start(opts: ServeOptions) -> None:
    import asyncio

    from orbitrig import config as cfg
    from orbitrig.errors import ConfigError
    from orbitrig.service.rig_service import BrokerSettings, ServiceError, ServiceSettings
    from orbitrig.service.settings import supervision_policy

    # every option checked before the log is set up: a serve refused leaves no log file, no handler
    if not (opts.log_max_mb > 0 and opts.log_backups >= 0):
        fail(f"--log-max-mb {opts.log_max_mb:g} / --log-backups {opts.log_backups}: a size > 0 and a count >= 0")
    password = o.broker_password(opts)
    abort = o.abort_account(opts, password)
    try:
        rig = cfg.load_rig(opts.config)
        if not opts.sim:
            cfg.check_on_the_rig(rig, "the service was not started")
        broker_settings = BrokerSettings.from_url(
            opts.broker, username=opts.username, password=password, tls_ca=opts.tls_ca, abort=abort
        )
        folder = opts.matrices or Path(rig.file).resolve().parent / "matrices"
        settings = ServiceSettings(
            rig_id=opts.rig_id,
            matrices_dir=folder,
            prefix=opts.prefix,
            supervision_policy=supervision_policy(opts.supervision_policy),
            supervision_timeout=opts.supervision_timeout,
            client_id=opts.client_id,
            catalog_url=opts.catalog,
            draw_figures=opts.draw_figures,
            runs_dir=opts.out,
        )
    except (ConfigError, ServiceError) as err:
        fail(str(err))
    sim = _checked_run_options(opts, folder)
    try:
        setup_service_log(
            verbose=opts.verbose, log_file=opts.log_file, max_mb=opts.log_max_mb, backups=opts.log_backups
        )
    except OSError as err:
        fail(f"--log-file: cannot open {opts.log_file}: {err.strerror or err}")
    if sim is not None:  # in the service's log: the scenario of every run (--sim-config, else the default)
        warn_other_scenario(rig, sim[1])
    try:
        asyncio.run(_serve(rig, settings, broker_settings, opts, sim))
    except* ServiceError as group:
        fail("; ".join(str(e) for e in group.exceptions), 1)


def _checked_run_options(opts: ServeOptions, folder: Path):
    """The runs' options checked (exit 2 if not); with --sim the simulator's (SimConfig, Scenario) of
    --sim-config (else the default scenario), checked as sweep checks it: every run's (None: the rig)."""
    from orbitrig.cli.scenarios import needs_sim, sim_scenario
    from orbitrig.cli.sim_options import speedup_problem

    needs_sim(opts.sim, opts.sim_config)
    sim = sim_scenario(opts.sim_config) if opts.sim else None
    problem = speedup_problem(opts.speedup)
    if problem is not None:
        fail(problem)
    if opts.confirm not in (ConfirmMode.REMOTE, ConfirmMode.AUTO):
        fail(f"--confirm: one of remote, auto, not {opts.confirm!r}")
    if opts.confirm == ConfirmMode.AUTO and not opts.sim:
        fail("--confirm auto only with --sim (a real rig needs an operator)")
    if not folder.is_dir():
        fail(f"matrix folder: {'a file, not a folder' if folder.exists() else 'no such folder'}: {folder} (--matrices)")
    if opts.catalog is not None:
        _check_catalog_url(opts.catalog)
    return sim


def _check_catalog_url(url: str) -> None:
    """--catalog names a database the catalog supports, and its extra is installed (exit 2 if not):
    found at the start, not as each point fails to be added."""
    try:
        from orbitrig.catalog.errors import CatalogUsageError
        from orbitrig.catalog.store import check_url
    except ModuleNotFoundError as err:
        fail(
            f"--catalog needs {err.name}, which is not installed: pip install -e '.[catalog]' in orbitrig's source tree"
        )
    try:
        check_url(url, "--catalog")
    except CatalogUsageError as err:
        fail(str(err))


def build_service(
    rig,
    settings,
    broker_settings,
    *,
    out: Path,
    sim_rig=None,
    confirm=ConfirmMode.REMOTE,
    reload: Path | None = None,
    scenario=None,
):
    """The RigService of `orbitrig serve`: each run gets a fresh RunEngine (the engine of
    `orbitrig sweep`; on the simulator `sim_rig` when given, running `scenario`, which each run
    records: orbitrig.run.rig_io.Scenario) writing to OUT/<date>-<matrix>/.
    ``reload``: the rig configuration file, loaded again (with its active calibration record)
    at each start, a start refused when it no longer loads; None: ``rig`` for every run."""

    from orbitrig import config as cfg
    from orbitrig.config import Drives
    from orbitrig.run.engine import RunEngine
    from orbitrig.run.plan import make_plan
    from orbitrig.run.rig_io import RigAccess
    from orbitrig.service.rig_service import RigService
    from orbitrig.store.identity import claim_dir
    from rigunits import utc_stamp

    if sim_rig is not None:
        from orbitrig.cli.simulated_rig import simulated_access

        access = simulated_access(sim_rig, scenario)
    else:
        access = RigAccess.of_rig(rig)
    current = [rig]  # the rig configuration of the latest start

    def load_matrix(path: Path):
        if reload is not None:
            node = None if sim_rig is None else sim_rig.can_node_id  # the simulator's CAN node, as it started
            current[0] = _reloaded(reload, current[0], on_the_rig=sim_rig is None, scenario=scenario, sim_node=node)
        # every problem of this matrix on this rig, before anything moves; the plan is run as it is
        return make_plan(cfg.load_matrix(path), current[0])

    def new_engine(name: str, matrix):
        run_dir = claim_dir(out, f"{utc_stamp()}-{name}")  # made new: no other process's
        run_access = access if sim_rig is not None else RigAccess.of_rig(current[0])
        return RunEngine(current[0], out_dir=run_dir, access=run_access, confirm_mode=confirm)

    def drive_link() -> tuple[str, Drives]:
        """The drives of the latest start's rig configuration (the simulator's: at its own address),
        for a stop or abort with no run holding them, asked at the time it is sent."""
        url = access.endpoints.modbus_url if sim_rig is not None else current[0].transports.modbus_url
        return url, current[0].drives

    return RigService(
        settings,
        broker_settings,
        engine_factory=new_engine,
        load_matrix=load_matrix,
        drive_link=drive_link,
        rig_check=lambda: require_answers(current[0], access if sim_rig is not None else None),
    )


async def require_answers(rig, sim_access=None) -> None:
    """The transports of `rig` (on the simulator: at `sim_access`'s endpoints), each opened once
    before a start's run folder is made (orbitrig.run.rig_answers: RigUnreachable if one does not answer)."""
    from orbitrig.run.rig_answers import at_endpoints, require_transports

    checked = rig if sim_access is None else at_endpoints(rig, sim_access.endpoints)
    await require_transports(checked, "orbitrig serve --sim ...", "no run folder was made")


def _reloaded(file: Path, previous, *, on_the_rig: bool, scenario=None, sim_node: int | None = None):
    """The rig configuration in ``file`` as it is now (its change since ``previous`` logged);
    CommandRefused with the configuration's error when it does not load, or (``on_the_rig``)
    when its active calibration record was measured on the simulator, or when it reads another CAN
    node id than ``sim_node``, the simulator's node (started as the rig.toml of `serve --sim` read: a
    run would find no node and fail after can_heartbeat_timeout_s); on the simulator's
    ``scenario`` a record measured on another scenario is warned of (warn_other_scenario)."""
    import logging

    from orbitrig import config as cfg
    from orbitrig.errors import ConfigError
    from orbitrig.service.rig_service import CommandRefused

    try:
        rig = cfg.load_rig(file)
        if on_the_rig:
            cfg.check_on_the_rig(rig)
    except ConfigError as err:
        raise CommandRefused(f"the rig configuration does not load: {err}") from None
    node = rig.transports.can_node_id
    if sim_node is not None and node != sim_node:
        raise CommandRefused(
            f"{file}: [transports] can_node_id {node}: the simulator's CAN node is node {sim_node}, as "
            "`orbitrig serve --sim` started it; restart the service to read another node"
        )
    if scenario is not None:
        warn_other_scenario(rig, scenario)
    if (rig.text, rig.record_text) != (previous.text, previous.record_text):
        logging.getLogger("orbitrig.cli.serve").warning(
            "rig configuration %s changed since the last start: calibration record %s (was %s)",
            file,
            rig.calibration_record,
            previous.calibration_record,
        )
    return rig


def warn_other_scenario(rig, scenario) -> None:
    """Log a warning (standard error and --log-file) when the active record was measured on another
    simulator scenario than ``scenario``'s (orbitrig.config.other_scenario): the service's start and
    each start of a run on the simulator; its runs are corrected with that scenario's."""
    import logging

    from orbitrig.config import other_scenario

    warning = other_scenario(rig, scenario.name, scenario.text)
    if warning is not None:
        logging.getLogger("orbitrig.cli.serve").warning("%s", warning)


async def _serve(rig, settings, broker_settings, opts: ServeOptions, sim) -> None:
    import asyncio
    import logging

    from orbitrig.cli.signals import hand_over, log_ignored, refuse_suspension, second_signal, signal_name, watched
    from orbitrig.service.leaving import LEAVE_GRACE_S

    shutdown = asyncio.Event()
    loop = asyncio.get_running_loop()
    from orbitrig.run.heap import tune_heap
    from orbitrig.run.modbus_log import keep_pymodbus_off_the_terminal

    keep_pymodbus_off_the_terminal()
    tune_heap()  # bounded memory over months (orbitrig.run.heap)
    services: list[RigService] = []
    leaving: set[asyncio.Task[None]] = set()
    cut: list[str] = []  # the signals that came before the service existed
    main = loop.create_task(_serve_until_shutdown(rig, settings, broker_settings, opts, sim, shutdown, services))

    def on_signal(sig: int) -> None:
        """The first: the run stops at once with a ramp (no run: both drives' emergency stop, as an
        MQTT abort no run carries out); another: it aborts (no run: the emergency stop again). A run
        whose disk does not return is left once its drives are stopped: 2 s after another signal
        while it waits for a disk that stalls, or after the service's whole wait for it
        (orbitrig.service.leaving). Before the service exists (--sim: its simulator starting) the
        start is cut short: nothing is opened but the simulator, which is ended (killed at another)."""
        name = signal_name(sig)
        if not services:
            cut.append(name)
            main.cancel()
        elif shutdown.is_set():
            services[0].abort_run(f"{second_signal(name)} while shutting down")
            if services[0].run_waits_for_disk:  # not a run that is still stopping or storing in time
                _leave_later(leaving, services[0], second_signal(name), LEAVE_GRACE_S)
        else:
            services[0].shutdown_cause = name
            services[0].stop_drives_on_signal(name)
            _leave_later(leaving, services[0], f"{name}: the run did not end within its wait", None)
        shutdown.set()

    for sig in watched():
        loop.add_signal_handler(sig, on_signal, sig)
    refuse_suspension(loop, "serve", logging.getLogger("orbitrig.cli.serve").warning)
    log_ignored("serve")
    try:
        await _started_or_cut(main, cut)
    finally:
        hand_over(loop)  # later signals recorded only: the service's way out has stopped the drives


async def _started_or_cut(main, cut: list[str]) -> None:
    """The service's task `main` to its end; cut short by the signals in `cut` before the service
    existed: said (logged), its simulator (--sim) ended, no drive link opened, nothing left running."""
    import asyncio
    import logging

    try:
        await main
    except asyncio.CancelledError:
        if not cut or not main.cancelled():
            raise
        logging.getLogger("orbitrig.cli.serve").warning(
            "%s before the service was up: not started; nothing was opened but the simulator (--sim), which has ended",
            cut[0],
        )


def _leave_later(tasks: set, service: RigService, why: str, grace: float | None) -> None:
    """A task that ends the process (exit 1) if the service's run is still waiting for its disk
    once its drives are stopped and `grace` s (None: the service's own wait) have passed."""
    import asyncio

    task = asyncio.get_running_loop().create_task(_leave(service, why, grace), name="leave-without-disk")
    tasks.add(task)
    task.add_done_callback(tasks.discard)


async def _leave(service: RigService, why: str, grace: float | None) -> None:
    import contextlib
    import os

    from orbitrig.cli.failure import error_line
    from orbitrig.cli.terminal import say

    words = await service.leave_without_disk(why, grace)  # logged there (each record flushed as written)
    if words is None:
        return
    try:
        with contextlib.suppress(OSError):
            say(error_line(words, command="serve"), err=True)
    finally:  # without joining the thread the stalled disk holds (an interpreter's exit would wait for it)
        from orbitrig.cli.service_log import written
        from orbitrig.service.leaving import LEAVE_GRACE_S

        written(LEAVE_GRACE_S)  # the log's records so far, unless its reader does not read
        os._exit(1)


async def _serve_until_shutdown(rig, settings, broker_settings, opts: ServeOptions, sim, shutdown, services) -> None:
    """The service (with --sim on the simulator running `sim`, its (SimConfig, Scenario)) until
    `shutdown`; `services` gets it once built; on the rig, which transports answer is logged once."""
    import asyncio
    import contextlib

    from orbitrig.run.rig_answers import say_what_answers

    async with contextlib.AsyncExitStack() as stack:
        sim_rig = scenario = None
        if sim is not None:
            from orbitrig.cli.sim_options import DEFAULT_SPEEDUP
            from orbitrig.cli.simulated_rig import simulated_rig

            speedup = opts.speedup or DEFAULT_SPEEDUP
            node = rig.transports.can_node_id  # the simulator's CAN node answers as the node rig.toml reads
            sim_rig, sim_access = await stack.enter_async_context(
                simulated_rig(speedup, sim[0], sim[1], can_node_id=node)
            )
            scenario = sim_access.scenario  # --sim-config's (else the default), recorded by each run
        service = build_service(
            rig,
            settings,
            broker_settings,
            out=opts.out,
            sim_rig=sim_rig,
            confirm=ConfirmMode(opts.confirm),
            reload=Path(rig.file),
            scenario=scenario,
        )
        services.append(service)
        if sim is None:  # on the rig: which transports answer, said once (a stop meanwhile waits for it)
            asked = asyncio.create_task(say_what_answers(rig, "orbitrig.cli.serve"))
            service.port_asked_by(asked)
            stack.callback(asked.cancel)
        await service.serve(shutdown)
    if service.signal_stop_failed is not None:  # the drives may turn on: exit 1, not 0
        from orbitrig.service.rig_service import ServiceError

        raise ServiceError(f"{service.signal_stop_why}: {service.signal_stop_failed}")
