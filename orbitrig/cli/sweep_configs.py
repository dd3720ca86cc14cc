"""The configuration `orbitrig sweep` runs with: the rig configuration and the matrix read from
their files, or on --resume the run's own (stored in run.h5), with what is given again checked
against them (a matrix must be the same; a rig configuration may differ only where a resume
may: orbitrig.config.resume); and the plan made of them, before anything starts."""

from __future__ import annotations

import typer


def load_plan(config, matrix, *, sim: bool, store, dry_run: bool):
    """The plan of this sweep: matrix checked against the rig and expanded, before anything starts;
    on --resume (``store``: the run resumed, orbitrig.cli.sweep_resume.open_run) in the order of
    the points the run started with (orbitrig.run.run_dir.started_order)."""
    from orbitrig.run.plan import make_plan

    rig, mat = configs(config, matrix, sim=sim, store=store, dry_run=dry_run)
    plan = make_plan(mat, rig)
    if store is not None:  # the order the run started with, as the resume runs it (its dry run shows that one)
        from orbitrig.run.run_dir import started_order

        plan = started_order(plan, store)
    return plan


def configs(config, matrix, *, sim: bool, store, dry_run: bool):
    """(rig configuration, matrix) of this sweep: from --config and --matrix, or on --resume the
    run's own (``store``: the run resumed)."""
    from orbitrig import config as cfg
    from orbitrig.errors import ConfigError

    if store is not None:
        rig_text, matrix_text, was_sim = store.stored_configs()
        if was_sim != sim:
            raise ConfigError(
                str(store.layout.header),
                [
                    f"this run was made {'on the simulator' if was_sim else 'on the rig'}: "
                    f"resume it {'with' if was_sim else 'without'} --sim"
                ],
            )
        record = stored_record(store)
        rig = cfg.rig_from_text(rig_text, f"{store.layout.header}:rig_config", record)
        if config:  # the devices may have moved; nothing the data depend on may change
            rig = given_again(cfg.load_rig(config), rig, store.dir)
        mat = cfg.matrix_from_text(matrix_text, f"{store.layout.header}:matrix_config")  # with the design it stored
        if matrix:  # given again: with the stored design, the lab's design file is not read
            mat = given_matrix(cfg.matrix_file(matrix, rig_path=config), mat)
        if matrix and mat.text != matrix_text:  # before the simulator or any drive is started
            raise ConfigError(
                mat.file,
                [
                    f"{cfg.matrix_differs(store.dir, matrix_text, mat.text)}; "
                    "resume without --matrix (the stored one is used)"
                ],
            )
        return rig, mat
    rig = cfg.load_rig(config)
    if not sim:  # a record measured on the simulator: refused, the dry run's plan included
        cfg.check_on_the_rig(rig, "no run directory was made")
    if matrix is None and not sim and not dry_run:
        raise typer.BadParameter(
            "--matrix NAME|FILE is required on the rig (--sim defaults to the demo)", param_hint="--matrix"
        )
    path = cfg.matrix_file(matrix, rig_path=config) if matrix else cfg.default_matrix_path(rig_path=config)
    return rig, cfg.load_matrix(path)


def given_matrix(path, stored):
    """--matrix FILE of a --resume, with the design of the ``stored`` matrix when the run stored it."""
    from orbitrig import config as cfg

    text, file = cfg.read_text(path)
    return cfg.matrix_from_text(stored.as_stored(text), file)


def given_again(given, stored, run):
    """`given` (--config on --resume) when it differs from the `stored` rig configuration only
    where a resume may (orbitrig.config.resume); else a ConfigError naming the differences."""
    from orbitrig.config import MAY_CHANGE, resume_differences
    from orbitrig.errors import ConfigError

    differences = resume_differences(stored, given)
    if differences:
        may = "; ".join(MAY_CHANGE)
        raise ConfigError(
            given.file,
            [
                f"differs from the rig configuration of the run being resumed in {run} in "
                f"{', '.join(differences)}; the remaining points must be measured as the first ones: "
                f"resume without --config (the stored one is used), or change only {may}"
            ],
        )
    return given


def stored_record(store) -> str | None:
    """The calibration record's text a resumed run stored, refused (ConfigError naming run.json)
    when it is not the text the run started with: its SHA-256 is not the provenance's
    ``calibration_record_sha256`` (run.json edited since, or the text gone, when the rig
    configuration would read a record of that name from the lab's folder instead). The points
    measured from then on would be corrected by another record than the provenance names. A
    provenance without that key is refused too: the key came with the provenance and the record
    text (run.json's format did not change), so only a run storing neither lacks it honestly."""
    from orbitrig import config as cfg

    text = store.stored_record()
    prov = store.stored_provenance()
    if "calibration_record_sha256" not in prov:
        if not prov and text is None:  # a run written before provenance and record text were stored
            return text
        raise cfg.ConfigError(
            str(store.layout.header),
            [
                "key 'provenance.calibration_record_sha256' is missing: every run that stores a provenance "
                "or a calibration record text records it, so the stored record cannot be checked against "
                "the one the run started with. Put run.json back as the run wrote it, or start a new run"
            ],
        )
    then = str(prov["calibration_record_sha256"] or "")  # "": the run started with no record
    if (text is None and not then) or (text is not None and cfg.digest(text) == then):
        return text
    now = f"its SHA-256 is {cfg.digest(text)[:12]}..." if text is not None else "it is not there"
    raise cfg.ConfigError(
        str(store.layout.header),
        [
            f"key 'calibration_record_text': the calibration record stored in this run is not the one it "
            f"started with: {now}, the run's provenance (calibration_record_sha256) says {then[:12] + '...' if then else 'none'}; "
            "the points resumed would be corrected by another record than the run names. Put run.json "
            "back as the run wrote it, or start a new run"
        ],
    )
